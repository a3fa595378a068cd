// SPDX-License-Identifier: Apache-2.0
// The `tinyline` command line is one executable with sub-commands, parsed
// with <tinyline/common/cli.hpp> (CLI11). Each command group lives in its own
// file under tools/commands/ and registers itself with a static
// CommandRegistration, so adding one edits no shared file:
//
//   CommandRun setup_bag(cli::App& cmd);   // declares options, returns what to run
//   static const tinyline::tools::CommandRegistration kBag{
//       "bag", "record, play, inspect and recover MCAP bags", &setup_bag};
//
// A command returns the process exit code: 0 success, 1 failure (with a
// message on stderr naming what and where), 2 bad usage (a CLI11 parse error
// or a UsageError).
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include <tinyline/bus/registry.hpp>

namespace tinyline::cli {
class App;
}

namespace tinyline::tools {

/// Bad usage found after parsing (e.g. a process group the file lacks): exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What a sub-command runs once its command line parsed; returns the exit code.
using CommandRun = std::function<int()>;
/// Declares a sub-command's options and positionals on `cmd`; their values
/// land in state the returned CommandRun holds.
using CommandSetup = CommandRun (*)(cli::App& cmd);

struct CommandInfo {
  std::string name;
  std::string summary;
  CommandSetup setup;
};

std::vector<CommandInfo>& command_table();

struct CommandRegistration {
  CommandRegistration(std::string name, std::string summary, CommandSetup setup) {
    command_table().push_back(CommandInfo{std::move(name), std::move(summary), setup});
  }
};

/// Every node type of the project (all packages' register_nodes()).
bus::NodeRegistry& node_registry();

/// Where shipped launch files, scenes and calibrations live: the source tree
/// when run from a build tree, <prefix>/share/tinyline when installed.
std::string share_dir();

}  // namespace tinyline::tools
