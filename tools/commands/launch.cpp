// SPDX-License-Identifier: Apache-2.0
// tinyline launch FILE [name:=value ...] [--duration S] [--until TOPIC] [--threads N] [--no-table] [--process NAME]
//
// One process runs the nodes without a process group; each group gets a child
// process (this same executable with --process NAME), supervised here. Topics
// crossing processes travel over DDS (docs/dds.md).
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <thread>
#include <filesystem>
#include <memory>

#include <fmt/format.h>

#include <tinyline/bus/names.hpp>
#include <tinyline/dds/bridge.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"
#include "../src/graph_runner.hpp"
#include "../src/process_plan.hpp"
#include "../src/roudi.hpp"
#include "../src/supervisor.hpp"

namespace tinyline::tools {
namespace {

struct LaunchArgs {
  std::string file;
  std::vector<std::string> assignments;  // name:=value
  std::optional<double> duration_s;
  std::optional<std::string> until_topic;
  int threads = 2;
  bool no_table = false;
  bool check = false;
  std::optional<std::string> process;
  double dds_wait_s = 10.0;
  bool rejoin = false;
  bool start_gate = false;
  double respawn_delay_s = 1.0;
  double grace_s = 5.0;
};

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

/// How many of the planned remote peers the bridge sees now.
struct PeerCount {
  bool all = true;       ///< every planned peer is matched
  bool some = true;      ///< each expected kind of peer is matched at least once
  std::string counts;    ///< a fingerprint, to see when it stops changing
  std::string short_of;  ///< what is missing, for the log
};

PeerCount count_peers(const dds::Bridge& bridge, const std::vector<dds::PeerExpectation>& expect) {
  const auto stats = bridge.stats();
  PeerCount c;
  for (const auto& e : expect) {
    std::size_t r = 0, w = 0;
    for (const auto& s : stats)
      if (s.topic == e.topic) r = s.remote_readers, w = s.remote_writers;
    c.all = c.all && r >= e.readers && w >= e.writers;
    c.some = c.some && (e.readers == 0 || r > 0) && (e.writers == 0 || w > 0);
    c.counts += fmt::format("{}:{}/{};", e.topic, r, w);
    if (r < e.readers || w < e.writers) {
      c.short_of += fmt::format("{}{}: {} of {} remote subscriber(s), {} of {} remote publisher(s)",
                                c.short_of.empty() ? "" : "; ", e.topic, r, e.readers, w, e.writers);
    }
  }
  return c;
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
    const PeerCount c = count_peers(bridge, expect);
    if (c.all) return;
    if (c.counts != last) {
      last = c.counts;
      last_change = SC::now();
    }
    const auto stable = SC::now() - last_change;
    if ((c.some && stable >= std::chrono::milliseconds(500)) || stable >= std::chrono::seconds(2) ||
        SC::now() >= deadline || interrupted()) {
      log.info("rejoined the running graph with the peers still there ({})", c.short_of);
      return;
    }
    ::poll(nullptr, 0, 20);  // discovery has no event to wait on here: a bounded poll of the counts
  }
}

std::string dds_table(const std::vector<dds::LinkStats>& links) {
  std::string s = fmt::format("over DDS:\n{:<34} {:>11} {:>11} {:>10} {:>10} {:>9} {:>7}\n", "topic", "remote subs",
                              "remote pubs", "sent", "received", "no reader", "errors");
  for (const auto& l : links) {
    s += fmt::format("{:<34} {:>11} {:>11} {:>10} {:>10} {:>9} {:>7}\n", l.topic, l.remote_readers, l.remote_writers,
                     l.sent, l.received, l.unmatched, l.decode_errors + l.write_errors + l.incompatible);
  }
  return s;
}

/// The file read, checked and split into processes; the nodes of this one built.
struct Loaded {
  launch::LaunchPlan plan;
  GraphPlan graph;
  std::vector<std::shared_ptr<bus::Node>> nodes;
};

Loaded load(const LaunchArgs& a, const std::shared_ptr<bus::Context>& ctx) {
  launch::LoadOptions lo;
  lo.share_dir = share_dir();
  lo.args = parsing::assignments(a.assignments);
  Loaded l;
  l.plan = launch::load_launch_file(a.file, lo);
  l.graph = plan_processes(l.plan, node_registry());  // builds and configures every node once: the whole file is valid
  if (a.process && l.graph.find(*a.process) == nullptr) {
    std::string known;
    for (const auto& p : l.graph.processes)
      if (!p.name.empty()) known += (known.empty() ? "" : ", ") + p.name;
    throw UsageError(
        fmt::format("{} has no process group '{}' (groups: {})", a.file, *a.process, known.empty() ? "none" : known));
  }
  l.nodes = launch::instantiate(l.plan, node_registry(), ctx, a.process.value_or(""));
  return l;
}

int print_check(const LaunchArgs& a, const Loaded& l) {
  fmt::print("{}: {} node(s), valid\n", a.file, l.plan.nodes.size());
  for (const auto& p : l.graph.processes) {
    if (p.name.empty() && p.nodes.empty()) continue;
    fmt::print("  process {}: {} node(s){}\n", p.name.empty() ? "(launching)" : "'" + p.name + "'", p.nodes.size(),
               p.uses_dds() ? fmt::format(", on DDS: {}", p.dds.all ? std::string("all topics")
                                                                    : fmt::format("{}", fmt::join(p.dds.topics, " ")))
                            : "");
  }
  for (const auto& w : l.graph.warnings) fmt::print("  warning: {}\n", w);
  return 0;
}

/// The DDS bridge of this process, if it has anything to share (nullptr otherwise).
std::shared_ptr<dds::Bridge> make_bridge(const LaunchArgs& a, const Loaded& l, const ProcessPlan& mine,
                                         const std::shared_ptr<bus::Context>& ctx) {
  if (!mine.uses_dds()) return nullptr;
  dds::BridgeOptions bo;
  const std::string stem = std::filesystem::path(a.file).stem().stem().string();
  bo.settings = dds_settings(l.plan, a.process ? *a.process : stem);
  bo.selection = mine.dds;
  return dds::Bridge::create(ctx, bo);
}

/// One child per process group, unless this is one of them.
std::unique_ptr<Supervisor> start_children(const LaunchArgs& a, const GraphPlan& graph) {
  SupervisorOptions so;
  so.respawn_delay_s = a.respawn_delay_s;
  so.grace_s = a.grace_s;
  auto supervisor = std::make_unique<Supervisor>(so);
  if (a.process) return supervisor;
  for (const auto& p : graph.processes) {
    if (p.name.empty()) continue;
    ChildSpec c;
    c.name = p.name;
    c.nodes = p.nodes;
    c.respawn = p.respawn;
    c.gated = true;
    c.restart_args = {"--rejoin"};
    c.argv = {self_exe(), "launch", a.file};
    c.argv.insert(c.argv.end(), a.assignments.begin(), a.assignments.end());
    c.argv.insert(c.argv.end(), {"--process", p.name, "--no-table", "--start-gate", "--threads",
                                 std::to_string(a.threads), "--dds-wait", fmt::format("{}", a.dds_wait_s)});
    supervisor->start(std::move(c));
  }
  return supervisor;
}

/// Before the nodes start: the bridge meets its peers, and every process
/// waits at a gate the supervisor opens once all of them are ready.
void wait_before_start(const LaunchArgs& a, const Loaded& l, const ProcessPlan& mine, dds::Bridge* bridge,
                       Supervisor& supervisor, const bus::Context& ctx) {
  const auto wait = std::chrono::milliseconds(static_cast<long>(a.dds_wait_s * 1000));
  if (bridge) {
    bridge->start();
    if (!mine.expect.empty() && a.rejoin) {
      wait_for_live_peers(*bridge, mine.expect, wait, bridge->logger());
    } else if (!mine.expect.empty()) {
      const auto r = bridge->wait_for_peers(mine.expect, wait);
      if (!r.ok) {
        bridge->logger().warn("starting without every DDS peer after {:.1f} s: {}", wait.count() / 1000.0, r.missing);
      }
    }
  }
  // Matched peers are not running peers: a process that matched early
  // would start its sources while another still waits for its own peers,
  // with nothing yet taking its messages off the queues.
  const auto gate_limit = 2 * wait + std::chrono::seconds(20);  // a child's start-up and its own wait
  if (a.process && a.start_gate) wait_at_start_gate(gate_limit + std::chrono::seconds(10), ctx.logger("/launch"));
  if (a.process || !l.graph.has_groups()) return;
  const auto deadline = std::chrono::steady_clock::now() + gate_limit;
  while (!supervisor.all_ready() && !interrupted() && std::chrono::steady_clock::now() < deadline) {
    supervisor.poll(std::chrono::milliseconds(20));
  }
  if (const auto late = supervisor.not_ready(); !late.empty() && !interrupted()) {
    fmt::print(stderr, "[launch] starting although process(es) {} did not get ready within {:.1f} s\n",
               fmt::join(late, ", "), gate_limit.count() / 1000.0);
  }
  supervisor.open_gates();
}

/// A message was published on `topic` in this process.
bool published_on(const bus::Graph& graph, const std::string& topic) {
  for (const auto& t : graph.topics())
    if (t.name == topic) return t.published > 0;
  return false;
}

/// Why --until cannot end this run: its topic is published only in another
/// process, whose messages this one never sees ("" when it can).
std::string until_problem(const LaunchArgs& a, const GraphPlan& g, const ProcessPlan& mine) {
  if (!a.until_topic || mine.uses.count(*a.until_topic) != 0) return {};
  for (const auto& p : g.processes) {
    if (&p == &mine || p.publishes.count(*a.until_topic) == 0) continue;
    return fmt::format(
        "--until {}: published only in process '{}', which this process does not see; --until watches the "
        "process it is given to (a topic a node of it publishes or subscribes)",
        *a.until_topic, p.name);
  }
  return {};
}

int run_launch(const LaunchArgs& a) {
  std::unique_ptr<Supervisor> roudi;  // goes last: every process using it has stopped by then
  auto ctx = bus::Context::create();
  Loaded l;
  try {
    l = load(a, ctx);
  } catch (const launch::LaunchError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  if (a.check) return print_check(a, l);
  if (!a.process) {
    for (const auto& w : l.graph.warnings) fmt::print(stderr, "[launch] warning: {}\n", w);
  }
  const ProcessPlan& mine = *l.graph.find(a.process.value_or(""));
  if (const std::string why = until_problem(a, l.graph, mine); !why.empty()) {
    fmt::print(stderr, "{}: {}\n", a.file, why);
    return 1;
  }
  if (!a.process && l.plan.dds.shared_memory) roudi = provide_roudi(share_dir() + "/config/roudi.toml");
  std::shared_ptr<dds::Bridge> bridge;
  try {
    bridge = make_bridge(a, l, mine, ctx);
  } catch (const dds::DdsError& e) {
    fmt::print(stderr, "{}: DDS: {}\n", a.file, e.what());
    return 1;
  }
  if (bridge) {
    bridge->announce_parameters(l.nodes);
    l.nodes.push_back(bridge);
  }
  auto supervisor = start_children(a, l.graph);

  RunOptions ro;
  ro.duration_s = a.duration_s;
  ro.threads = a.threads;
  ro.table = !a.no_table;
  ro.before_spin = [&] { wait_before_start(a, l, mine, bridge.get(), *supervisor, *ctx); };
  ro.before_stop = [&] {
    if (bridge) bridge->expect_departures();  // the other processes are stopping too
    supervisor->stop_all();
  };
  const bool supervising = !a.process && l.graph.has_groups();
  if (supervising || a.until_topic) {
    ro.tick = [&](std::chrono::milliseconds budget) {
      if (roudi) roudi->poll(std::chrono::milliseconds(0));
      if (supervising) {
        supervisor->poll(budget);
      } else {
        std::this_thread::sleep_for(budget);  // a CLI waiting for the end, not a test
      }
      return !(a.until_topic && published_on(ctx->graph(), *a.until_topic));
    };
  }
  int rc = run_nodes(ctx, l.nodes, ro);
  if (bridge) fmt::print("{}", dds_table(bridge->stats()));
  supervisor.reset();
  if (a.until_topic && !published_on(ctx->graph(), *a.until_topic) && !interrupted()) {
    // The guard: the run was to end on that message and did not.
    fmt::print(stderr, "error: {}: no message on {} before the run ended{}\n", a.file, *a.until_topic,
               a.duration_s ? fmt::format(" (--duration {} s)", *a.duration_s) : std::string());
    rc = 1;
  }
  return rc;
}

CommandRun setup_launch(cli::App& cmd) {
  auto a = std::make_shared<LaunchArgs>();
  cmd.add_option("file", a->file, "the launch file")->required();
  cmd.add_option("args", a->assignments, "launch arguments, name:=value")->type_name("NAME:=VALUE");
  cmd.add_option("--duration", a->duration_s, "stop after S seconds")->type_name("S")->check(cli::seconds());
  cmd.add_option("--until", a->until_topic,
                 "end when a message is published on TOPIC (absolute, in this process); with --duration as a guard: "
                 "ending without that message is an error (exit 1)")
      ->type_name("TOPIC")
      ->check([](const std::string& t) -> std::string {
        if (t.empty() || t[0] != '/') return "must be an absolute topic name (/...)";
        if (t == "/") return "'/' is the root namespace, not a topic";
        try {
          bus::validate_name(t, "topic");  // "/", "//x" and "/a b" would run and only fail at the end
        } catch (const std::exception& e) {
          return e.what();
        }
        return {};
      });
  cmd.add_option("--threads", a->threads, "executor threads per process")->capture_default_str()->check(cli::threads());
  cmd.add_flag("--no-table", a->no_table, "no live table");
  cmd.add_flag("--check", a->check, "validate the file, build its nodes and load their inputs, then exit");
  cmd.add_option("--process", a->process,
                 "run only this process group (what the supervisor starts; also how to start one group on another "
                 "machine)");
  cmd.add_option("--dds-wait", a->dds_wait_s, "longest wait for DDS peers before nodes start [s]")
      ->capture_default_str()
      ->check(cli::non_negative());
  cmd.add_flag("--rejoin", a->rejoin,
               "with --process: a restart into a running graph; wait only for the peers still alive");
  cmd.add_flag("--start-gate", a->start_gate,
               "with --process: once the peers are matched, print a ready line and start the nodes when stdin gets "
               "a line (the supervisor does this so all processes start together)");
  cmd.add_option("--respawn-delay", a->respawn_delay_s, "wait before restarting a crashed process [s]")
      ->capture_default_str()
      ->check(cli::non_negative());
  cmd.add_option("--grace", a->grace_s, "after Ctrl-C, wait this long before killing [s]")
      ->capture_default_str()
      ->check(cli::non_negative());
  cmd.footer(
      "Runs the nodes of a launch file (ROS 2 YAML launch shape) and shows a live table of topics with rates and\n"
      "drops. Stops on Ctrl-C, after --duration, or at the first message on the --until topic. Nothing starts\n"
      "unless the whole file is valid and every node's input files load: errors name the file, line and reason.\n\n"
      "Nodes in a process group (group: {process: NAME, ...} or node: {process: NAME}) run in their own process,\n"
      "started and supervised here: their output comes back prefixed with [NAME], a crashed one is restarted if a\n"
      "node in it says respawn: true, Ctrl-C stops them all. Topics used by several processes, and those the file\n"
      "marks with dds, travel over DDS (Cyclone DDS, ROS 2 naming; loopback only unless CYCLONEDDS_URI says\n"
      "otherwise, see docs/dds.md).");
  return [a] { return run_launch(*a); };
}

const CommandRegistration kLaunch{"launch", "run the nodes of a launch file", &setup_launch};

}  // namespace
}  // namespace tinyline::tools
