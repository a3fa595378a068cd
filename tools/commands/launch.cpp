// tinyline launch FILE [name:=value ...] [--duration S] [--threads N] [--no-table] [--process NAME]
//
// One process runs the nodes without a process group; each group gets a child
// process (this same executable with --process NAME), supervised here. Topics
// crossing processes travel over DDS (docs/dds.md).
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include <tinyline/dds/bridge.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/args.hpp"
#include "../src/graph_runner.hpp"
#include "../src/process_plan.hpp"
#include "../src/supervisor.hpp"

namespace tinyline::tools {
namespace {

constexpr const char* kHelp = R"(usage: tinyline launch FILE [name:=value ...] [options]

Runs the nodes of a launch file (ROS 2 YAML launch shape) and shows a live
table of topics with rates and drops. Stops on Ctrl-C or after --duration.
Nothing starts unless the whole file is valid: errors name the file, line and
reason.

Nodes in a process group (group: {process: NAME, ...} or node: {process: NAME})
run in their own process, started and supervised here: their output comes
back prefixed with [NAME], a crashed one is restarted if a node in it says
respawn: true, Ctrl-C stops them all. Topics used by several processes, and
those the file marks with dds, travel over DDS (Cyclone DDS, ROS 2 naming;
loopback only unless CYCLONEDDS_URI says otherwise, see docs/dds.md).

options:
  --duration S        stop after S seconds
  --threads N         executor threads per process (default 2)
  --no-table          no live table
  --check             validate the file and build its nodes, then exit
  --process NAME      run only this process group (what the supervisor starts;
                      also how to start one group on another machine)
  --dds-wait S        longest wait for DDS peers before nodes start (default 10)
  --rejoin            with --process: a restart into a running graph; wait only
                      for the peers still alive (discovery settles), not for all
  --start-gate        with --process: once the peers are matched, print a ready
                      line and start the nodes when stdin gets a line (the
                      supervisor does this so all processes start together)
  --respawn-delay S   wait before restarting a crashed process (default 1)
  --grace S           after Ctrl-C, wait this long before killing (default 5)
)";

std::string self_exe() {
  std::error_code ec;
  const auto p = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot find this executable (/proc/self/exe): " + ec.message());
  return p.string();
}

/// A supervised child at the start gate: says it is ready, then waits for
/// the supervisor's line on stdin (EOF, Ctrl-C or `limit` also let it go).
void wait_at_start_gate(std::chrono::milliseconds limit, const bus::Logger& log) {
  fmt::print("{}\n", kReadyLine);
  std::fflush(stdout);
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!interrupted()) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      log.warn("the supervisor did not open the start gate within {:.1f} s; starting anyway", limit.count() / 1000.0);
      return;
    }
    pollfd p{STDIN_FILENO, POLLIN, 0};
    const int n = ::poll(&p, 1, static_cast<int>(std::min<long>(left.count(), 100)));
    if (n > 0) {
      char c[16];
      (void)!read(STDIN_FILENO, c, sizeof(c));  // a line or EOF: go
      return;
    }
  }
}

/// A restart into a running graph: peers that died stay gone, so waiting
/// for every planned one would stall until `limit`. Waits until everything
/// planned is matched, or the counts stayed the same for half a second with
/// each expected kind of peer matched at least once (two seconds if some
/// kind has no match at all: its only peer may be gone), and says what it
/// started without.
void wait_for_live_peers(const dds::Bridge& bridge, const std::vector<dds::PeerExpectation>& expect,
                         std::chrono::milliseconds limit, const bus::Logger& log) {
  using SC = std::chrono::steady_clock;
  const auto deadline = SC::now() + limit;
  std::string last;
  auto last_change = SC::now();
  for (;;) {
    const auto stats = bridge.stats();
    bool all = true, some = true;
    std::string counts, short_of;
    for (const auto& e : expect) {
      std::size_t r = 0, w = 0;
      for (const auto& s : stats)
        if (s.topic == e.topic) r = s.remote_readers, w = s.remote_writers;
      all = all && r >= e.readers && w >= e.writers;
      some = some && (e.readers == 0 || r > 0) && (e.writers == 0 || w > 0);
      counts += fmt::format("{}:{}/{};", e.topic, r, w);
      if (r < e.readers || w < e.writers) {
        short_of += fmt::format("{}{}: {} of {} remote subscriber(s), {} of {} remote publisher(s)",
                                short_of.empty() ? "" : "; ", e.topic, r, e.readers, w, e.writers);
      }
    }
    if (all) return;
    if (counts != last) {
      last = counts;
      last_change = SC::now();
    }
    const auto stable = SC::now() - last_change;
    if ((some && stable >= std::chrono::milliseconds(500)) || stable >= std::chrono::seconds(2) ||
        SC::now() >= deadline || interrupted()) {
      log.info("rejoined the running graph with the peers still there ({})", short_of);
      return;
    }
    ::poll(nullptr, 0, 20);  // discovery has no event to wait on here: a bounded poll of the counts
  }
}

std::string dds_table(const std::vector<dds::LinkStats>& links) {
  std::string s = fmt::format("over DDS:\n{:<34} {:>11} {:>11} {:>10} {:>10} {:>9} {:>7}\n", "topic", "remote subs",
                              "remote pubs", "sent", "received", "no reader", "errors");
  for (const auto& l : links) {
    s += fmt::format("{:<34} {:>11} {:>11} {:>10} {:>10} {:>9} {:>7}\n", l.topic, l.remote_readers,
                     l.remote_writers, l.sent, l.received, l.unmatched,
                     l.decode_errors + l.write_errors + l.incompatible);
  }
  return s;
}

int cmd_launch(const std::vector<std::string>& argv) {
  Args a(argv, {"--duration", "--threads", "--process", "--dds-wait", "--respawn-delay", "--grace"},
         {"--no-table", "--check", "--help", "-h", "--start-gate", "--rejoin"});
  if (a.flag("--help") || a.flag("-h")) {
    fmt::print("{}", kHelp);
    return 0;
  }
  if (a.positional().empty()) throw UsageError("which launch file? (tinyline launch --help)");
  const std::string file = a.positional()[0];
  launch::LoadOptions lo;
  lo.share_dir = share_dir();
  for (std::size_t i = 1; i < a.positional().size(); ++i) lo.args.insert(split_assignment(a.positional()[i]));
  const std::optional<std::string> only = a.value("--process");

  auto ctx = bus::Context::create();
  std::vector<std::shared_ptr<bus::Node>> nodes;
  launch::LaunchPlan plan;
  GraphPlan graph;
  try {
    plan = launch::load_launch_file(file, lo);
    graph = plan_processes(plan, node_registry());  // builds every node once: the whole file is valid
    if (only && graph.find(*only) == nullptr) {
      std::string known;
      for (const auto& p : graph.processes)
        if (!p.name.empty()) known += (known.empty() ? "" : ", ") + p.name;
      throw UsageError(fmt::format("{} has no process group '{}' (groups: {})", file, *only,
                                   known.empty() ? "none" : known));
    }
    nodes = launch::instantiate(plan, node_registry(), ctx, only.value_or(""));
  } catch (const launch::LaunchError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  const std::string me = only.value_or("");
  const ProcessPlan& mine = *graph.find(me);
  if (a.flag("--check")) {
    fmt::print("{}: {} node(s), valid\n", file, plan.nodes.size());
    for (const auto& p : graph.processes) {
      if (p.name.empty() && p.nodes.empty()) continue;
      fmt::print("  process {}: {} node(s){}\n", p.name.empty() ? "(launching)" : "'" + p.name + "'", p.nodes.size(),
                 p.uses_dds() ? fmt::format(", on DDS: {}", p.dds.all ? std::string("all topics")
                                                                      : fmt::format("{}", fmt::join(p.dds.topics, " ")))
                              : "");
    }
    for (const auto& w : graph.warnings) fmt::print("  warning: {}\n", w);
    return 0;
  }
  if (!only) {
    for (const auto& w : graph.warnings) fmt::print(stderr, "[launch] warning: {}\n", w);
  }

  // The DDS bridge of this process, if it has anything to share.
  std::shared_ptr<dds::Bridge> bridge;
  if (mine.uses_dds()) {
    dds::BridgeOptions bo;
    const std::string stem = std::filesystem::path(file).stem().stem().string();
    bo.settings = dds_settings(plan, me.empty() ? stem : me);
    bo.selection = mine.dds;
    try {
      bridge = dds::Bridge::create(ctx, bo);
    } catch (const dds::DdsError& e) {
      fmt::print(stderr, "{}: DDS: {}\n", file, e.what());
      return 1;
    }
    nodes.push_back(bridge);
  }

  // The children: one per process group, unless this is one of them.
  SupervisorOptions so;
  so.respawn_delay_s = a.number("--respawn-delay", 1.0);
  so.grace_s = a.number("--grace", 5.0);
  auto supervisor = std::make_unique<Supervisor>(so);
  if (!only) {
    for (const auto& p : graph.processes) {
      if (p.name.empty()) continue;
      ChildSpec c;
      c.name = p.name;
      c.nodes = p.nodes;
      c.respawn = p.respawn;
      c.gated = true;
      c.restart_args = {"--rejoin"};
      c.argv = {self_exe(), "launch", file};
      for (std::size_t i = 1; i < a.positional().size(); ++i) c.argv.push_back(a.positional()[i]);
      c.argv.insert(c.argv.end(), {"--process", p.name, "--no-table", "--start-gate", "--threads",
                                   std::to_string(static_cast<int>(a.number("--threads", 2))), "--dds-wait",
                                   fmt::format("{}", a.number("--dds-wait", 10.0))});
      supervisor->start(std::move(c));
    }
  }

  RunOptions ro;
  if (a.value("--duration")) ro.duration_s = a.number("--duration", 0);
  ro.threads = static_cast<int>(a.number("--threads", 2));
  ro.table = !a.flag("--no-table");
  const auto wait_ms = std::chrono::milliseconds(static_cast<long>(a.number("--dds-wait", 10.0) * 1000));
  const bool gated = only && a.flag("--start-gate");
  ro.before_spin = [&] {
    if (bridge) {
      bridge->start();
      if (!mine.expect.empty() && a.flag("--rejoin")) {
        wait_for_live_peers(*bridge, mine.expect, wait_ms, bridge->logger());
      } else if (!mine.expect.empty()) {
        const auto r = bridge->wait_for_peers(mine.expect, wait_ms);
        if (!r.ok) {
          bridge->logger().warn("starting without every DDS peer after {:.1f} s: {}", wait_ms.count() / 1000.0,
                                r.missing);
        }
      }
    }
    // Matched peers are not running peers: a process that matched early
    // would start its sources while another still waits for its own peers,
    // with nothing yet taking its messages off the queues. So every process
    // waits at a gate the supervisor opens once all of them are ready.
    const auto gate_limit = 2 * wait_ms + std::chrono::seconds(20);  // a child's start-up and its own wait
    if (gated) wait_at_start_gate(gate_limit + std::chrono::seconds(10), ctx->logger("/launch"));
    if (!only && graph.has_groups()) {
      const auto deadline = std::chrono::steady_clock::now() + gate_limit;
      while (!supervisor->all_ready() && !interrupted() && std::chrono::steady_clock::now() < deadline) {
        supervisor->poll(std::chrono::milliseconds(20));
      }
      if (const auto late = supervisor->not_ready(); !late.empty() && !interrupted()) {
        fmt::print(stderr, "[launch] starting although process(es) {} did not get ready within {:.1f} s\n",
                   fmt::join(late, ", "), gate_limit.count() / 1000.0);
      }
      supervisor->open_gates();
    }
  };
  ro.before_stop = [&] {
    if (bridge) bridge->expect_departures();  // the other processes are stopping too
    supervisor->stop_all();
  };
  if (!only && graph.has_groups()) {
    ro.tick = [&](std::chrono::milliseconds budget) {
      supervisor->poll(budget);
      return true;
    };
  }
  const int rc = run_nodes(ctx, nodes, ro);
  if (bridge) fmt::print("{}", dds_table(bridge->stats()));
  supervisor.reset();
  return rc;
}

const CommandRegistration kLaunch{"launch", "run the nodes of a launch file", &cmd_launch};

}  // namespace
}  // namespace tinyline::tools
