// SPDX-License-Identifier: Apache-2.0
// What only the sub-commands' command lines share: name:=value
// arguments and nested commands (bag record, topic list). The checks for
// numbers are every program's: <tinyline/common/cli.hpp>.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <tinyline/common/cli.hpp>

#include <tinyline/tools/command.hpp>

namespace tinyline::tools::parsing {

/// "name:=value" -> {name, value}; throws UsageError otherwise.
std::pair<std::string, std::string> split_assignment(const std::string& s);
/// Every name:=value of `args`; throws UsageError on one without ":=".
std::map<std::string, std::string> assignments(const std::vector<std::string>& args);

/// A command of a group: `tinyline bag record`, `tinyline topic hz`.
struct Nested {
  const char* name;
  const char* summary;
  CommandSetup setup;
};
/// Declares `subs` under `cmd` (one of them required) and returns a run that
/// runs the one named on the command line.
CommandRun nested(cli::App& cmd, const std::vector<Nested>& subs);

/// The command path of the deepest sub-command parsed ("bag record").
std::string command_path(const cli::App& app);

}  // namespace tinyline::tools::parsing
