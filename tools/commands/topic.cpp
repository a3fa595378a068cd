// SPDX-License-Identifier: Apache-2.0
// tinyline topic list | echo TOPIC | hz TOPIC: a running graph seen through
// DDS, from any process on the same DDS domain (ROS_DOMAIN_ID, CYCLONEDDS_URI).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <deque>
#include <map>
#include <set>

#include <fmt/format.h>

#include <tinyline/dds/naming.hpp>
#include <tinyline/dds/participant.hpp>
#include <tinyline/msg/yaml_writer.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"

namespace tinyline::tools {
namespace {

std::atomic<int> g_stop{0};
extern "C" void on_topic_signal(int sig) { g_stop.store(sig); }

struct SignalGuard {
  SignalGuard() {
    g_stop.store(0);
    std::signal(SIGINT, on_topic_signal);
    std::signal(SIGTERM, on_topic_signal);
  }
  ~SignalGuard() {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
  }
};

// The options of the three commands (each uses its part).
struct TopicArgs {
  std::string topic;
  std::optional<int> domain;
  double wait_s = 10.0;
  bool all = false;
  bool verbose = false;
  long count = 0;
  std::string type;
  std::size_t max_array = 16;
  std::optional<double> duration_s;
  long messages = 0;
  std::size_t window = 10000;
};

dds::Settings settings_from(const TopicArgs& a) {
  dds::Settings s = dds::Settings::from_environment();
  if (a.domain) s.domain_id = dds::check_domain_id(*a.domain, "--domain");
  s.process_name = "tinyline topic";
  for (const auto& note : s.notes) fmt::print(stderr, "tinyline topic: {}\n", note);
  return s;
}

std::chrono::milliseconds millis(double s) { return std::chrono::milliseconds(static_cast<long>(s * 1000)); }

int cmd_list(const TopicArgs& a) {
  dds::Participant p(settings_from(a));
  dds::Discovery d(p);
  const auto eps = d.settle(std::chrono::milliseconds(300), millis(a.wait_s));
  struct Row {
    std::string type;
    std::size_t pubs = 0, subs = 0;
    std::set<std::string> processes;
  };
  std::map<std::string, Row> rows;
  for (const auto& e : eps) {
    if (!e.topic && !a.all) continue;
    Row& r = rows[e.topic.value_or(e.dds_topic)];
    r.type = e.type.value_or(e.dds_type);
    (e.writer ? r.pubs : r.subs)++;
    r.processes.insert(e.owner.known() ? e.owner.process : "(other)");
  }
  if (rows.empty()) {
    fmt::print(stderr,
               "no topics on DDS domain {} (is a graph running with the same ROS_DOMAIN_ID and "
               "CYCLONEDDS_URI?)\n",
               p.settings().domain_id);
    return 1;
  }
  fmt::print("{:<34} {:<34} {:>4} {:>4}  {}\n", "topic", "type", "pubs", "subs", "processes");
  for (const auto& [name, r] : rows) {
    fmt::print("{:<34} {:<34} {:>4} {:>4}  {}\n", name, r.type, r.pubs, r.subs, fmt::join(r.processes, ", "));
    if (a.verbose) {
      for (const auto& e : eps) {
        if (e.topic.value_or(e.dds_topic) != name) continue;
        fmt::print("    {} {} [{}]\n", e.writer ? "publisher " : "subscriber", e.owner.describe(), e.qos.describe());
      }
    }
  }
  return 0;
}

/// Waits for a publisher of `topic`; returns its endpoint data.
std::optional<dds::DiscoveredEndpoint> find_publisher(const dds::Discovery& d, const std::string& topic,
                                                      std::chrono::milliseconds wait) {
  const std::string dt = dds::dds_topic_name(topic);
  const auto eps = d.wait_for(
      [&](const std::vector<dds::DiscoveredEndpoint>& v) {
        return g_stop.load() != 0 ||
               std::any_of(v.begin(), v.end(), [&](const auto& e) { return e.writer && e.dds_topic == dt; });
      },
      wait);
  for (const auto& e : eps)
    if (e.writer && e.dds_topic == dt) return e;
  return std::nullopt;
}

/// A reader QoS every discovered writer of the topic can serve (what ros2 topic
/// echo does: reliable / latched only if all publishers are).
dds::EndpointQos qos_for(const dds::Discovery& d, const std::string& topic) {
  dds::EndpointQos q;
  q.depth = 100;
  const std::string dt = dds::dds_topic_name(topic);
  for (const auto& e : d.snapshot()) {
    if (!e.writer || e.dds_topic != dt) continue;
    q.reliable &= e.qos.reliable;
    q.transient_local &= e.qos.transient_local;
  }
  return q;
}

int cmd_echo(const TopicArgs& a) {
  const std::string& topic = a.topic;
  SignalGuard sig;
  dds::Participant p(settings_from(a));
  dds::Discovery d(p);
  const auto wait = millis(a.wait_s);
  std::string dds_type;
  const msg::TypeSupport* ts = nullptr;
  if (!a.type.empty()) {
    ts = msg::find_type_support(a.type);
    if (ts == nullptr)
      throw UsageError("unknown message type '" + a.type +
                       "' (tinyline nodes lists node types; "
                       "message types are pkg/msg/Type)");
    dds_type = ts->dds_type_name();
  }
  const auto pub = find_publisher(d, topic, wait);
  if (!pub && ts == nullptr) {
    if (g_stop.load() != 0) return 0;
    fmt::print(stderr, "no publisher of {} appeared within {:.1f} s on DDS domain {}\n", topic, wait.count() / 1000.0,
               p.settings().domain_id);
    return 1;
  }
  if (ts == nullptr) {
    ts = dds::find_type_by_dds_name(pub->dds_type);
    if (ts == nullptr) {
      fmt::print(stderr,
                 "{} carries {}, which is not a tinyline message type; cannot decode it "
                 "(tinyline topic hz still measures it)\n",
                 topic, pub->dds_type);
      return 1;
    }
    dds_type = pub->dds_type;
  }
  dds::RawReader reader(p, dds::dds_topic_name(topic), dds_type, qos_for(d, topic));
  const long count = a.count;
  const std::size_t max_array = a.max_array;
  long shown = 0;
  while (g_stop.load() == 0 && (count <= 0 || shown < count)) {
    reader.take(std::chrono::milliseconds(100), [&](const dds::RawSample& s) {
      if (count > 0 && shown >= count) return;
      try {
        auto m = ts->deserialize(s.cdr);
        msg::YamlWriter y(max_array);
        ts->to_yaml(m.get(), y);
        fmt::print("{}---\n", y.str());
        std::fflush(stdout);
        ++shown;
      } catch (const std::exception& e) {
        fmt::print(stderr, "{}: a message that does not decode as {}: {}\n", topic, ts->name, e.what());
      }
    });
  }
  return 0;
}

int cmd_hz(const TopicArgs& a) {
  const std::string& topic = a.topic;
  SignalGuard sig;
  dds::Participant p(settings_from(a));
  dds::Discovery d(p);
  const auto wait = millis(a.wait_s);
  const auto pub = find_publisher(d, topic, wait);
  if (!pub) {
    if (g_stop.load() != 0) return 0;
    fmt::print(stderr, "no publisher of {} appeared within {:.1f} s on DDS domain {}\n", topic, wait.count() / 1000.0,
               p.settings().domain_id);
    return 1;
  }
  dds::RawReader reader(p, pub->dds_topic, pub->dds_type, qos_for(d, topic));
  using SC = std::chrono::steady_clock;
  const std::size_t window = a.window;
  const long limit = a.messages;
  const auto start = SC::now();
  // A negative duration means none (GCC's maybe-uninitialized trips on an optional here).
  const auto duration = a.duration_s ? millis(*a.duration_s) : std::chrono::milliseconds(-1);
  std::deque<SC::time_point> arrivals;
  long total = 0;
  auto next_report = start + std::chrono::seconds(1);
  auto report = [&] {
    if (arrivals.size() < 2) {
      fmt::print("no new messages\n");
      return;
    }
    std::vector<double> dt;
    for (std::size_t i = 1; i < arrivals.size(); ++i) {
      dt.push_back(std::chrono::duration<double>(arrivals[i] - arrivals[i - 1]).count());
    }
    double mean = 0;
    for (double x : dt) mean += x;
    mean /= static_cast<double>(dt.size());
    double var = 0;
    for (double x : dt) var += (x - mean) * (x - mean);
    const double sd = std::sqrt(var / static_cast<double>(dt.size()));
    fmt::print("average rate: {:.3f}\n\tmin: {:.4f}s max: {:.4f}s std dev: {:.5f}s window: {}\n", 1.0 / mean,
               *std::min_element(dt.begin(), dt.end()), *std::max_element(dt.begin(), dt.end()), sd, arrivals.size());
    std::fflush(stdout);
  };
  while (g_stop.load() == 0) {
    reader.take(std::chrono::milliseconds(50), [&](const dds::RawSample&) {
      arrivals.push_back(SC::now());  // arrival times, as ros2 topic hz measures
      while (arrivals.size() > window) arrivals.pop_front();
      ++total;
    });
    const auto now = SC::now();
    if (now >= next_report) {
      report();
      next_report += std::chrono::seconds(1);
    }
    if (limit > 0 && total >= limit) break;
    if (duration.count() >= 0 && now - start >= duration) break;
  }
  report();
  return 0;
}

// Runs `fn` and turns a DDS failure into a message naming the command.
CommandRun guarded(const char* name, int (*fn)(const TopicArgs&), std::shared_ptr<TopicArgs> a) {
  return [name, fn, a] {
    try {
      return fn(*a);
    } catch (const dds::DdsError& e) {
      fmt::print(stderr, "tinyline topic {}: DDS: {}\n", name, e.what());
      return 1;
    }
  };
}

void add_common(cli::App& cmd, TopicArgs& a, double wait_default) {
  a.wait_s = wait_default;
  cmd.add_option("--wait", a.wait_s, "how long to wait for discovery / a publisher [s]")
      ->type_name("S")
      ->capture_default_str()
      ->check(cli::non_negative());
  cmd.add_option("--domain", a.domain, "DDS domain (default ROS_DOMAIN_ID or 0)")->check(cli::whole(0, 232));
}

void add_topic(cli::App& cmd, TopicArgs& a) {
  cmd.add_option("topic", a.topic, "an absolute topic name")
      ->required()
      ->check(cli::Validator(
          [](std::string& t) -> std::string {
            return t.empty() || t[0] != '/' ? "topic '" + t + "' must be absolute (start with '/')" : std::string();
          },
          "/TOPIC"));
}

CommandRun setup_list(cli::App& cmd) {
  auto a = std::make_shared<TopicArgs>();
  add_common(cmd, *a, 2.0);
  cmd.add_flag("--all", a->all, "DDS topics that are not ROS topics too");
  cmd.add_flag("-v", a->verbose, "every endpoint with its QoS");
  return guarded("list", &cmd_list, a);
}

CommandRun setup_echo(cli::App& cmd) {
  auto a = std::make_shared<TopicArgs>();
  add_topic(cmd, *a);
  add_common(cmd, *a, 10.0);
  cmd.add_option("--count", a->count, "stop after N messages (0: Ctrl-C)")->check(cli::count());
  cmd.add_option("--type", a->type, "decode as this type, pkg/msg/Type (default: the publisher's)");
  cmd.add_option("--max-array", a->max_array, "elements of long arrays to show (0: all)")
      ->capture_default_str()
      ->check(cli::count());
  return guarded("echo", &cmd_echo, a);
}

CommandRun setup_hz(cli::App& cmd) {
  auto a = std::make_shared<TopicArgs>();
  add_topic(cmd, *a);
  add_common(cmd, *a, 10.0);
  cmd.add_option("--duration", a->duration_s, "stop after S seconds")->type_name("S")->check(cli::seconds());
  cmd.add_option("--messages", a->messages, "stop after N messages (0: Ctrl-C)")->check(cli::count());
  cmd.add_option("--window", a->window, "rate over the last N messages")
      ->capture_default_str()
      ->check(cli::whole(2, 100000000));
  return guarded("hz", &cmd_hz, a);
}

CommandRun setup_topic(cli::App& cmd) {
  cmd.footer(
      "Looks at the topics of running graphs over DDS: every topic that travels between processes, or that a\n"
      "launch file marks with dds. Uses the DDS domain and configuration of the environment (ROS_DOMAIN_ID,\n"
      "CYCLONEDDS_URI; the loopback default otherwise), like every tinyline process and ROS 2 node.");
  return parsing::nested(cmd, {{"list", "topics with their type, publishers, subscribers and processes", &setup_list},
                               {"echo", "print each message as YAML, '---' between messages", &setup_echo},
                               {"hz", "print the publishing rate once a second", &setup_hz}});
}

const CommandRegistration kTopic{"topic", "list, echo and measure topics of running graphs over DDS", &setup_topic};

}  // namespace
}  // namespace tinyline::tools
