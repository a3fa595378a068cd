// What the sub-commands' command lines share (CLI11): checks for the numbers
// they take, name:=value arguments, and nested commands (bag record, topic
// list). Every number is checked when parsed: a bad one is a usage error
// naming the option, never a silent default or a run that ignores it.
#pragma once

#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include <tinyline/tools/command.hpp>

namespace tinyline::tools::cli {

/// A finite number > `lo` (or >= with `inclusive`) and <= `hi`: NaN and
/// infinities are refused, as is anything out of bounds.
CLI::Validator finite_above(double lo, bool inclusive, double hi = std::numeric_limits<double>::max());
/// A duration in seconds: finite and > 0.
inline CLI::Validator seconds() { return finite_above(0.0, false); }
/// A wait, offset or rate that may be 0: finite and >= 0.
inline CLI::Validator non_negative() { return finite_above(0.0, true); }
/// A whole number in [lo, hi].
CLI::Validator whole(long long lo, long long hi);
/// A count that may be 0 (0 often means "no limit").
inline CLI::Validator count() { return whole(0, std::numeric_limits<long long>::max()); }
/// Executor threads: 1..kMaxThreads.
inline constexpr int kMaxThreads = 256;
inline CLI::Validator threads() { return whole(1, kMaxThreads); }

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
CommandRun nested(CLI::App& cmd, const std::vector<Nested>& subs);

/// The command path of the deepest sub-command parsed ("bag record").
std::string command_path(const CLI::App& app);

}  // namespace tinyline::tools::cli
