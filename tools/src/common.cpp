// SPDX-License-Identifier: Apache-2.0
#include <tinyline/tools/command.hpp>

#include <unistd.h>

#include <filesystem>

#include "register_all.hpp"

namespace tinyline::tools {

std::vector<CommandInfo>& command_table() {
  static std::vector<CommandInfo> table;
  return table;
}

bus::NodeRegistry& node_registry() {
  static bus::NodeRegistry r = [] {
    bus::NodeRegistry reg;
    register_all_nodes(reg);
    return reg;
  }();
  return r;
}

std::string share_dir() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share" / "tinyline";
    if (fs::exists(installed / "launch", ec)) return installed.string();
  }
  return TINYLINE_SOURCE_SHARE;  // running from a build tree
}

}  // namespace tinyline::tools
