// The `tinyline` command line is one executable with sub-commands. Each
// command group lives in its own file under tools/commands/ and registers
// itself with a static CommandRegistration, so adding one edits no shared file:
//
//   static int cmd_bag(const std::vector<std::string>& args);   // args after "bag"
//   static const tinyline::tools::CommandRegistration kBag{
//       "bag", "record, play, inspect and recover MCAP bags", &cmd_bag};
//
// A command returns the process exit code: 0 success, 1 failure (with a
// message on stderr naming what and where), 2 bad usage.
#pragma once

#include <string>
#include <vector>

#include <tinyline/bus/registry.hpp>

namespace tinyline::tools {

using CommandFn = int (*)(const std::vector<std::string>& args);

struct CommandInfo {
  std::string name;
  std::string summary;
  CommandFn fn;
};

std::vector<CommandInfo>& command_table();

struct CommandRegistration {
  CommandRegistration(std::string name, std::string summary, CommandFn fn) {
    command_table().push_back(CommandInfo{std::move(name), std::move(summary), fn});
  }
};

/// Every node type of the project (all packages' register_nodes()).
bus::NodeRegistry& node_registry();

/// Where shipped launch files, scenes and calibrations live: the source tree
/// when run from a build tree, <prefix>/share/tinyline when installed.
std::string share_dir();

}  // namespace tinyline::tools
