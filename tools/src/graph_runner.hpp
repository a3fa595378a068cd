// SPDX-License-Identifier: Apache-2.0
// Runs a set of nodes in this process until Ctrl-C or a duration, with a live
// table of topics (rates, drops) on a terminal. Shared by `launch` and `run`.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <tinyline/bus/node.hpp>

namespace tinyline::tools {

struct RunOptions {
  std::optional<double> duration_s;  ///< stop after this long (wall time)
  int threads = 2;                   ///< executor threads
  bool table = true;                 ///< live topic table (only on a terminal)
  double table_period_s = 1.0;
  bool summary = true;  ///< the topic table with average rates at the end
  /// Called about every 200 ms with the seconds run so far (a progress line).
  std::function<void(double elapsed_s)> progress;
  /// Runs after the nodes are on the executor and before it starts (the DDS
  /// bridge waits for its peers here).
  std::function<void()> before_spin;
  /// Called in the wait loop instead of sleeping, may block up to the given
  /// time (the launch supervisor forwards its children's output here);
  /// returning false ends the run.
  std::function<bool(std::chrono::milliseconds)> tick;
  /// Called when the run ends, while the local nodes still run (the launch
  /// supervisor stops its children here, so the last messages still arrive).
  std::function<void()> before_stop;
  /// Called once the local nodes stopped, before the summary.
  std::function<void()> on_stopping;
};

/// Runs the nodes; returns the exit code (0, or 1 if a node failed to start or to stop cleanly).
int run_nodes(const std::shared_ptr<bus::Context>& ctx, const std::vector<std::shared_ptr<bus::Node>>& nodes,
              const RunOptions& options);

/// Ctrl-C (SIGINT) or SIGTERM arrived during run_nodes (before_spin may poll it).
bool interrupted();

/// The topic table as text (the live view and the final summary).
std::string topic_table(const bus::Graph& graph, bus::RateMonitor& rates, bus::Time wall_now);

}  // namespace tinyline::tools
