// SPDX-License-Identifier: Apache-2.0
#include "roudi.hpp"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>

#include <fmt/format.h>

#include <tinyline/dds/settings.hpp>
#include "graph_runner.hpp"

namespace tinyline::tools {

namespace {

std::string find_on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path != nullptr ? path : "/usr/bin:/bin");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const std::string p = (dir.empty() ? std::string(".") : dir) + "/" + name;
    if (access(p.c_str(), X_OK) == 0) return p;
  }
  return {};
}

/// Waits until RouDi answers, it exits, or 10 s pass (RouDi maps its pools
/// first: a second or two for hundreds of MB). Forwards what it prints.
bool wait_until_up(Supervisor& s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!dds::roudi_running()) {
    if (s.running() == 0 || interrupted() || std::chrono::steady_clock::now() >= deadline) return false;
    s.poll(std::chrono::milliseconds(20));  // RouDi has no readiness signal but its socket
  }
  return true;
}

}  // namespace

std::unique_ptr<Supervisor> provide_roudi(const std::string& pools) {
  setenv("TINYLINE_SHARED_MEMORY", "1", 1);
  if (dds::roudi_running()) {
    fmt::print(stderr, "[launch] shared memory: using the RouDi already running on this machine\n");
    return nullptr;
  }
  const std::string exe = find_on_path("iox-roudi");
  if (exe.empty()) {
    fmt::print(stderr,
               "[launch] shared memory: iox-roudi is not installed (Debian package iceoryx); every process stays on "
               "loopback\n");
    return nullptr;
  }
  SupervisorOptions so;
  so.grace_s = 5.0;
  auto s = std::make_unique<Supervisor>(so);
  ChildSpec c;
  c.name = "roudi";
  c.argv = {exe, "-c", pools, "-l", "warning"};
  c.nodes = {fmt::format("iox-roudi with the pools of {}", pools)};
  s->start(std::move(c));
  if (!wait_until_up(*s)) {
    fmt::print(stderr, "[launch] shared memory: RouDi did not come up; every process stays on loopback\n");
    return nullptr;  // stops it if it still runs
  }
  fmt::print(stderr, "[launch] shared memory: RouDi (pid {}) runs for this launch\n", s->pid_of("roudi"));
  return s;
}

}  // namespace tinyline::tools
