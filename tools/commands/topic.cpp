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

#include "../src/args.hpp"

namespace tinyline::tools {
namespace {

constexpr const char* kHelp = R"(usage: tinyline topic list [--wait S] [--all] [-v]
       tinyline topic echo TOPIC [--count N] [--wait S] [--type PKG/msg/TYPE] [--max-array N]
       tinyline topic hz TOPIC [--duration S] [--messages N] [--window N] [--wait S]

Looks at the topics of running graphs over DDS: every topic that travels
between processes, or that a launch file marks with dds. Uses the DDS domain
and configuration of the environment (ROS_DOMAIN_ID, CYCLONEDDS_URI; the
loopback default otherwise), like every tinyline process and ROS 2 node.

  list   topics with their type, publishers, subscribers and processes
         (--all: DDS topics that are not ROS topics too; -v: every endpoint)
  echo   prints each message as YAML, '---' between messages
  hz     prints the publishing rate once a second

options:
  --wait S       how long to wait for discovery / a publisher (default 2 for
                 list, 10 for echo and hz)
  --count N      echo: stop after N messages
  --type T       echo: decode as this type (default: the publisher's)
  --max-array N  echo: elements of long arrays to show (default 16, 0: all)
  --duration S   hz: stop after S seconds
  --messages N   hz: stop after N messages
  --window N     hz: rate over the last N messages (default 10000)
  --domain N     DDS domain (default ROS_DOMAIN_ID or 0)
)";

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

dds::Settings settings_from(const Args& a) {
  dds::Settings s = dds::Settings::from_environment();
  if (a.value("--domain")) s.domain_id = dds::check_domain_id(static_cast<long long>(a.number("--domain", 0)), "--domain");
  s.process_name = "tinyline topic";
  for (const auto& note : s.notes) fmt::print(stderr, "tinyline topic: {}\n", note);
  return s;
}

std::chrono::milliseconds seconds_option(const Args& a, const std::string& name, double fallback) {
  const double s = a.number(name, fallback);
  if (s < 0) throw UsageError(name + " must not be negative");
  return std::chrono::milliseconds(static_cast<long>(s * 1000));
}

std::string topic_arg(const Args& a, std::size_t i) {
  if (a.positional().size() <= i) throw UsageError("which topic? (tinyline topic --help)");
  const std::string t = a.positional()[i];
  if (t.empty() || t[0] != '/') throw UsageError("topic '" + t + "' must be absolute (start with '/')");
  return t;
}

int cmd_list(const Args& a) {
  dds::Participant p(settings_from(a));
  dds::Discovery d(p);
  const auto eps = d.settle(std::chrono::milliseconds(300), seconds_option(a, "--wait", 2.0));
  struct Row {
    std::string type;
    std::size_t pubs = 0, subs = 0;
    std::set<std::string> processes;
  };
  std::map<std::string, Row> rows;
  for (const auto& e : eps) {
    if (!e.topic && !a.flag("--all")) continue;
    Row& r = rows[e.topic.value_or(e.dds_topic)];
    r.type = e.type.value_or(e.dds_type);
    (e.writer ? r.pubs : r.subs)++;
    r.processes.insert(e.owner.known() ? e.owner.process : "(other)");
  }
  if (rows.empty()) {
    fmt::print(stderr, "no topics on DDS domain {} (is a graph running with the same ROS_DOMAIN_ID and "
               "CYCLONEDDS_URI?)\n", p.settings().domain_id);
    return 1;
  }
  fmt::print("{:<34} {:<34} {:>4} {:>4}  {}\n", "topic", "type", "pubs", "subs", "processes");
  for (const auto& [name, r] : rows) {
    fmt::print("{:<34} {:<34} {:>4} {:>4}  {}\n", name, r.type, r.pubs, r.subs, fmt::join(r.processes, ", "));
    if (a.flag("-v")) {
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

int cmd_echo(const Args& a) {
  const std::string topic = topic_arg(a, 1);
  SignalGuard sig;
  dds::Participant p(settings_from(a));
  dds::Discovery d(p);
  const auto wait = seconds_option(a, "--wait", 10.0);
  std::string dds_type;
  const msg::TypeSupport* ts = nullptr;
  if (auto t = a.value("--type")) {
    ts = msg::find_type_support(*t);
    if (ts == nullptr) throw UsageError("unknown message type '" + *t + "' (tinyline nodes lists node types; "
                                        "message types are pkg/msg/Type)");
    dds_type = ts->dds_type_name();
  }
  const auto pub = find_publisher(d, topic, wait);
  if (!pub && ts == nullptr) {
    if (g_stop.load() != 0) return 0;
    fmt::print(stderr, "no publisher of {} appeared within {:.1f} s on DDS domain {}\n", topic,
               wait.count() / 1000.0, p.settings().domain_id);
    return 1;
  }
  if (ts == nullptr) {
    ts = dds::find_type_by_dds_name(pub->dds_type);
    if (ts == nullptr) {
      fmt::print(stderr, "{} carries {}, which is not a tinyline message type; cannot decode it "
                 "(tinyline topic hz still measures it)\n", topic, pub->dds_type);
      return 1;
    }
    dds_type = pub->dds_type;
  }
  dds::RawReader reader(p, dds::dds_topic_name(topic), dds_type, qos_for(d, topic));
  const long count = static_cast<long>(a.number("--count", 0));
  const auto max_array = static_cast<std::size_t>(a.number("--max-array", 16));
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

int cmd_hz(const Args& a) {
  const std::string topic = topic_arg(a, 1);
  SignalGuard sig;
  dds::Participant p(settings_from(a));
  dds::Discovery d(p);
  const auto wait = seconds_option(a, "--wait", 10.0);
  const auto pub = find_publisher(d, topic, wait);
  if (!pub) {
    if (g_stop.load() != 0) return 0;
    fmt::print(stderr, "no publisher of {} appeared within {:.1f} s on DDS domain {}\n", topic,
               wait.count() / 1000.0, p.settings().domain_id);
    return 1;
  }
  dds::RawReader reader(p, pub->dds_topic, pub->dds_type, qos_for(d, topic));
  using SC = std::chrono::steady_clock;
  const std::size_t window = static_cast<std::size_t>(std::max(2.0, a.number("--window", 10000)));
  const long limit = static_cast<long>(a.number("--messages", 0));
  const auto start = SC::now();
  // A negative duration means none (GCC's maybe-uninitialized trips on an optional here).
  const auto duration = a.value("--duration") ? seconds_option(a, "--duration", 0) : std::chrono::milliseconds(-1);
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
               *std::min_element(dt.begin(), dt.end()), *std::max_element(dt.begin(), dt.end()), sd,
               arrivals.size());
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

int cmd_topic(const std::vector<std::string>& argv) {
  Args a(argv, {"--wait", "--count", "--type", "--max-array", "--duration", "--messages", "--window", "--domain"},
         {"--all", "-v", "--help", "-h"});
  if (a.flag("--help") || a.flag("-h") || a.positional().empty()) {
    fmt::print("{}", kHelp);
    return a.positional().empty() && !a.flag("--help") && !a.flag("-h") ? 2 : 0;
  }
  const std::string& sub = a.positional()[0];
  try {
    if (sub == "list") return cmd_list(a);
    if (sub == "echo") return cmd_echo(a);
    if (sub == "hz") return cmd_hz(a);
  } catch (const dds::DdsError& e) {
    fmt::print(stderr, "tinyline topic {}: DDS: {}\n", sub, e.what());
    return 1;
  }
  throw UsageError("unknown topic command '" + sub + "' (list, echo, hz)");
}

const CommandRegistration kTopic{"topic", "list, echo and measure topics of running graphs over DDS", &cmd_topic};

}  // namespace
}  // namespace tinyline::tools
