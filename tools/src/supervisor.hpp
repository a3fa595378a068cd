// SPDX-License-Identifier: Apache-2.0
// Child processes of `tinyline launch`: started, their output forwarded line
// by line with the process group's name in front, restarted when they die if
// asked, stopped with SIGINT (then SIGKILL after a grace period) at the end.
//
// Children live in their own process group (a terminal's Ctrl-C reaches the
// supervisor, which stops them in order) and die with the supervisor
// (PR_SET_PDEATHSIG), so a killed launch leaves nothing behind.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace tinyline::tools {

struct ChildSpec {
  std::string name;                ///< process group name, the prefix of its lines
  std::vector<std::string> argv;   ///< argv[0] is the executable path
  std::vector<std::string> nodes;  ///< its nodes, for reports
  bool respawn = false;
  /// The child runs `tinyline launch ... --start-gate`: it prints kReadyLine
  /// once its DDS peers are matched and starts its nodes when the supervisor
  /// opens the gates (its stdin gets a line), so no process starts its
  /// sources while another is still waiting for its own peers.
  bool gated = false;
  /// Appended to argv when the child is restarted (launch: --rejoin).
  std::vector<std::string> restart_args;
};

/// What a gated child prints (alone on a line of its stdout) when it is ready;
/// the supervisor does not forward it.
inline constexpr std::string_view kReadyLine = "[tinyline launch: ready]";

struct SupervisorOptions {
  double respawn_delay_s = 1.0;  ///< wait before restarting a dead child
  double grace_s = 5.0;          ///< after SIGINT, wait this long before SIGKILL
  std::FILE* out = stdout;       ///< children's stdout lines go here
  std::FILE* err = stderr;       ///< children's stderr lines and the supervisor's reports go here
};

class Supervisor {
 public:
  explicit Supervisor(SupervisorOptions options = {});
  ~Supervisor();  ///< stops every child still running
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  /// Starts a child. Throws std::runtime_error if it cannot be started.
  void start(ChildSpec spec);
  /// Forwards output for up to `budget`, reaps children that exited (reporting
  /// how), and restarts those that asked for it once their delay has passed.
  void poll(std::chrono::milliseconds budget);
  /// SIGINT to every child, SIGKILL to those still alive after the grace
  /// period; forwards what they print on the way out.
  void stop_all();

  /// Every gated child still running has said it is ready.
  bool all_ready() const;
  /// Names of the gated children still running that have not said so.
  std::vector<std::string> not_ready() const;
  /// Lets every gated child start its nodes; children started (or restarted)
  /// later start as soon as they are ready.
  void open_gates();
  /// Children that died on their own (not stopped by us), counted per death.
  int failures() const { return failures_; }
  /// Children running now.
  std::size_t running() const;
  pid_t pid_of(const std::string& name) const;

 private:
  struct Child;
  void spawn(Child& c);
  void forward(Child& c, int& fd, bool drain);
  void reap(bool stopping);

  SupervisorOptions options_;
  std::vector<std::unique_ptr<Child>> children_;
  int failures_ = 0;
  bool gates_open_ = false;
};

/// "exited with code 3" / "was killed by signal 9 (Killed)".
std::string describe_exit(int wait_status);

}  // namespace tinyline::tools
