#include "graph_runner.hpp"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <thread>

#include <fmt/format.h>

#include <tinyline/bus/executor.hpp>

namespace tinyline::tools {

namespace {
std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) { g_signal.store(sig); }

bus::Time wall_now() {
  return bus::Time{std::chrono::duration_cast<std::chrono::nanoseconds>(
                       std::chrono::system_clock::now().time_since_epoch())
                       .count()};
}
}  // namespace

std::string topic_table(const bus::Graph& graph, bus::RateMonitor& rates, bus::Time now) {
  std::string s = fmt::format("{:<34} {:<34} {:>4} {:>4} {:>9} {:>10} {:>8}\n", "topic", "type", "pubs", "subs",
                              "rate Hz", "published", "dropped");
  for (const auto& r : rates.sample(graph, now)) {
    s += fmt::format("{:<34} {:<34} {:>4} {:>4} {:>9.1f} {:>10} {:>8}\n", r.info.name, r.info.type,
                     r.info.publishers, r.info.subscriptions, r.rate_hz, r.info.published,
                     r.info.dropped + r.info.timeouts);
  }
  return s;
}

bool interrupted() { return g_signal.load() != 0; }

int run_nodes(const std::shared_ptr<bus::Context>& ctx, const std::vector<std::shared_ptr<bus::Node>>& nodes,
              const RunOptions& options) {
  bus::MultiThreadedExecutor ex(ctx->clock(), std::max(1, options.threads));
  for (const auto& n : nodes) ex.add_node(n);
  g_signal.store(0);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  if (options.before_spin) options.before_spin();

  std::atomic<bool> spin_done{false};
  std::string failure;
  std::thread spinner([&] {
    try {
      ex.spin();
    } catch (const std::exception& e) {
      failure = e.what();
    }
    spin_done.store(true);
  });

  const bool live = options.table && isatty(STDOUT_FILENO);
  bus::RateMonitor rates;
  rates.sample(ctx->graph(), wall_now());
  const auto start = std::chrono::steady_clock::now();
  auto next_table = start + std::chrono::duration<double>(options.table_period_s);
  std::size_t last_lines = 0;
  while (!spin_done.load() && g_signal.load() == 0) {
    const auto now = std::chrono::steady_clock::now();
    if (options.duration_s && now - start >= std::chrono::duration<double>(*options.duration_s)) break;
    if (live && now >= next_table) {
      const std::string t = topic_table(ctx->graph(), rates, wall_now());
      if (last_lines > 0) fmt::print("\033[{}A\033[J", last_lines);  // redraw in place
      fmt::print("{}", t);
      std::fflush(stdout);
      last_lines = static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n'));
      next_table = now + std::chrono::duration<double>(options.table_period_s);
    }
    if (options.tick) {
      if (!options.tick(std::chrono::milliseconds(50))) break;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));  // a CLI waiting for Ctrl-C, not a test
    }
  }
  if (options.before_stop) options.before_stop();
  ex.stop();
  spinner.join();
  bool stop_failed = false;  // a recorder that could not finish its file, say
  for (auto it = nodes.rbegin(); it != nodes.rend(); ++it) {
    try {
      (*it)->on_stop();
    } catch (const std::exception& e) {
      fmt::print(stderr, "node '{}' failed to stop cleanly: {}\n", (*it)->full_name(), e.what());
      stop_failed = true;
    }
  }
  if (options.on_stopping) options.on_stopping();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!failure.empty()) {
    fmt::print(stderr, "error: {}\n", failure);
    return 1;
  }
  // Final summary: average rates over the whole run.
  bus::RateMonitor whole;
  whole.sample(bus::Graph{}, bus::Time{});
  fmt::print("after {:.1f} s:\n{:<34} {:<34} {:>10} {:>9} {:>8}\n", elapsed, "topic", "type", "published",
             "avg Hz", "dropped");
  for (const auto& t : ctx->graph().topics()) {
    fmt::print("{:<34} {:<34} {:>10} {:>9.1f} {:>8}\n", t.name, t.type, t.published,
               elapsed > 0 ? static_cast<double>(t.published) / elapsed : 0.0, t.dropped + t.timeouts);
  }
  return stop_failed ? 1 : 0;
}

}  // namespace tinyline::tools
