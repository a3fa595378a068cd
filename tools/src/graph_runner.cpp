// SPDX-License-Identifier: Apache-2.0
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
  return bus::Time{
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count()};
}

using SteadyClock = std::chrono::steady_clock;

// Ctrl-C and SIGTERM end the run; restored to the default when it ends.
struct SignalScope {
  SignalScope() {
    g_signal.store(0);
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
  }
  ~SignalScope() {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
  }
};

// The executor on its own thread; a failure to start a node ends it.
class Spinner {
 public:
  explicit Spinner(bus::Executor& ex)
      : thread_([this, &ex] {
          try {
            ex.spin();
          } catch (const std::exception& e) {
            failure_ = e.what();
          }
          done_.store(true);
        }) {}
  void join() { thread_.join(); }
  bool done() const { return done_.load(); }
  const std::string& failure() const { return failure_; }  // after join()

 private:
  std::atomic<bool> done_{false};
  std::string failure_;
  std::thread thread_;
};

// The live table on a terminal, redrawn in place.
class LiveTable {
 public:
  LiveTable(const bus::Graph& g, const RunOptions& o)
      : graph_(g), options_(o), live_(o.table && isatty(STDOUT_FILENO)) {
    rates_.sample(graph_, wall_now());
    next_ = SteadyClock::now() + period();
  }
  void maybe_draw(SteadyClock::time_point now) {
    if (!live_ || now < next_) return;
    const std::string t = topic_table(graph_, rates_, wall_now());
    if (lines_ > 0) fmt::print("\033[{}A\033[J", lines_);
    fmt::print("{}", t);
    std::fflush(stdout);
    lines_ = static_cast<std::size_t>(std::count(t.begin(), t.end(), '\n'));
    next_ = now + period();
  }

 private:
  SteadyClock::duration period() const {
    return std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(options_.table_period_s));
  }
  const bus::Graph& graph_;
  const RunOptions& options_;
  const bool live_;
  bus::RateMonitor rates_;
  SteadyClock::time_point next_;
  std::size_t lines_ = 0;
};

// Waits for the end: Ctrl-C, --duration, the executor failing, or tick() saying so.
void wait_for_end(const bus::Graph& graph, const Spinner& spinner, const RunOptions& options,
                  SteadyClock::time_point start) {
  LiveTable table(graph, options);
  auto next_progress = start;
  while (!spinner.done() && g_signal.load() == 0) {
    const auto now = SteadyClock::now();
    const double elapsed = std::chrono::duration<double>(now - start).count();
    if (options.duration_s && elapsed >= *options.duration_s) break;
    table.maybe_draw(now);
    if (options.progress && now >= next_progress) {
      options.progress(elapsed);
      next_progress = now + std::chrono::milliseconds(200);
    }
    if (options.tick) {
      if (!options.tick(std::chrono::milliseconds(50))) break;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));  // a CLI waiting for Ctrl-C, not a test
    }
  }
}

// on_stop() of every node, the last added first; false if one failed (a
// recorder that could not finish its file, say).
bool stop_nodes(const std::vector<std::shared_ptr<bus::Node>>& nodes) {
  bool ok = true;
  for (auto it = nodes.rbegin(); it != nodes.rend(); ++it) {
    try {
      (*it)->on_stop();
    } catch (const std::exception& e) {
      fmt::print(stderr, "node '{}' failed to stop cleanly: {}\n", (*it)->full_name(), e.what());
      ok = false;
    }
  }
  return ok;
}

// Average rates over the whole run.
void print_summary(const bus::Graph& graph, double elapsed) {
  fmt::print("after {:.1f} s:\n{:<34} {:<34} {:>10} {:>9} {:>8}\n", elapsed, "topic", "type", "published", "avg Hz",
             "dropped");
  for (const auto& t : graph.topics()) {
    fmt::print("{:<34} {:<34} {:>10} {:>9.1f} {:>8}\n", t.name, t.type, t.published,
               elapsed > 0 ? static_cast<double>(t.published) / elapsed : 0.0, t.dropped + t.timeouts);
  }
}

}  // namespace

std::string topic_table(const bus::Graph& graph, bus::RateMonitor& rates, bus::Time now) {
  std::string s = fmt::format("{:<34} {:<34} {:>4} {:>4} {:>9} {:>10} {:>8}\n", "topic", "type", "pubs", "subs",
                              "rate Hz", "published", "dropped");
  for (const auto& r : rates.sample(graph, now)) {
    s += fmt::format("{:<34} {:<34} {:>4} {:>4} {:>9.1f} {:>10} {:>8}\n", r.info.name, r.info.type, r.info.publishers,
                     r.info.subscriptions, r.rate_hz, r.info.published, r.info.dropped + r.info.timeouts);
  }
  return s;
}

bool interrupted() { return g_signal.load() != 0; }

int run_nodes(const std::shared_ptr<bus::Context>& ctx, const std::vector<std::shared_ptr<bus::Node>>& nodes,
              const RunOptions& options) {
  bus::MultiThreadedExecutor ex(ctx->clock(), std::max(1, options.threads));
  for (const auto& n : nodes) ex.add_node(n);
  SignalScope signals;
  if (options.before_spin) options.before_spin();
  const auto start = SteadyClock::now();
  Spinner spinner(ex);
  wait_for_end(ctx->graph(), spinner, options, start);
  if (options.before_stop) options.before_stop();
  ex.stop();
  spinner.join();
  const bool stopped = stop_nodes(nodes);
  if (options.on_stopping) options.on_stopping();
  if (!spinner.failure().empty()) {
    fmt::print(stderr, "error: {}\n", spinner.failure());
    return 1;
  }
  if (options.summary) print_summary(ctx->graph(), std::chrono::duration<double>(SteadyClock::now() - start).count());
  return stopped ? 0 : 1;
}

}  // namespace tinyline::tools
