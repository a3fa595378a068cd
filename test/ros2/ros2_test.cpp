// SPDX-License-Identifier: Apache-2.0
// The real ROS 2 client against tinyline: rclpy on Fast DDS (ROS 2 Jazzy's
// default middleware, from the registry's wheels) with default settings, and
// tinyline processes with theirs. Each test runs in a network namespace of its
// own with a "network card" (in_netns.sh), so the ROS 2 node announces and
// multicasts as on a robot while nothing leaves the test's namespace.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <fmt/format.h>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/dds/bridge.hpp>
#include <tinyline/msg/sensor_msgs/laser_scan.hpp>
#include <tinyline/msg/std_msgs/string.hpp>
#include <tinyline/msg/tf2_msgs/tf_message.hpp>

#include "../dds/bridged_graph.hpp"
#include "../dds/child_process.hpp"

using namespace tinyline;
using namespace std::chrono_literals;
using StringMsg = std_msgs::msg::String;
using tinyline::testing::ChildProcess;
namespace tlt = tinyline::testing;

namespace {

const std::string kHere = std::string(TINYLINE_SOURCE_DIR) + "/test/ros2/";

// Fast DDS notices a killed participant when its lease (20 s by default)
// runs out; discovery of a late ROS 2 node takes up to one of our announcement
// periods (2.4 s). Deadlines are generous: they only bound a failure.
constexpr auto kDiscovery = 30s;
constexpr auto kLease = 60s;

#define REQUIRE_ROS2_SANDBOX()                                                                                    \
  do {                                                                                                            \
    if (std::getenv("TINYLINE_NETNS") == nullptr) {                                                               \
      const char* why = std::getenv("TINYLINE_NETNS_REASON");                                                     \
      GTEST_SKIP() << "needs a network namespace of its own (" << (why ? why : "run through in_netns.sh") << ")"; \
    }                                                                                                             \
    if (access(TINYLINE_VENV_PYTHON, X_OK) != 0) GTEST_SKIP() << "no test venv at " << TINYLINE_VENV_PYTHON;      \
  } while (0)

std::vector<std::string> peer(std::vector<std::string> args) {
  args.insert(args.begin(), {TINYLINE_VENV_PYTHON, kHere + "ros2_peer.py"});
  return args;
}

std::vector<std::string> cli(std::vector<std::string> args) {
  args.insert(args.begin(), TINYLINE_EXE);
  return args;
}

bool exited_ok(ChildProcess& p, std::chrono::milliseconds timeout) {
  const auto st = p.wait_exit(timeout);
  return st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0;
}

/// A tinyline process in this test process with the settings of the
/// environment (the defaults, in the sandbox).
struct Graph : tlt::BridgedGraph {
  Graph() : BridgedGraph(settings(), "ros2_side") {}
  static dds::Settings settings() {
    dds::Settings s = dds::Settings::from_environment();
    s.process_name = "tinyline_test";
    return s;
  }
};

/// The index make(string, i) in ros2_peer.py puts in the text.
std::unique_ptr<StringMsg> numbered(int i) {
  auto m = std::make_unique<StringMsg>();
  m->data = fmt::format("tinyline interop {}: grüße", i);
  return m;
}

/// Lines "GOT i ok" of a subscriber, as indices; a mismatch fails the test.
std::vector<int> got(const ChildProcess& p) {
  std::vector<int> out;
  for (const auto& l : p.lines()) {
    if (l.rfind("GOT ", 0) != 0) continue;
    EXPECT_NE(l.find(" ok"), std::string::npos) << l;
    out.push_back(std::stoi(l.substr(4)));
  }
  return out;
}

std::size_t count_lines(const ChildProcess& p, const std::string& prefix) {
  const auto lines = p.lines();
  return static_cast<std::size_t>(
      std::count_if(lines.begin(), lines.end(), [&](const std::string& l) { return l.rfind(prefix, 0) == 0; }));
}

std::vector<int> one_to(int n) {
  std::vector<int> v;
  for (int i = 1; i <= n; ++i) v.push_back(i);
  return v;
}

}  // namespace

// ------------------------------------------------------------------ discovery, both sides on defaults

TEST(Ros2Discovery, ADefaultRos2NodeAndADefaultTinylineProcessFindEachOtherBothWays) {
  REQUIRE_ROS2_SANDBOX();
  // The newcomer's case: nobody set anything, the machine has a network card.
  ChildProcess pulse(
      cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/chatter", "-p", "rate_hz:=20", "--no-table"}));
  ChildProcess listener(peer({"sub", "--type", "string", "--topic", "/chatter", "--count", "3", "--any"}));
  ASSERT_TRUE(exited_ok(listener, kDiscovery + 30s)) << listener.output() << pulse.output();
  EXPECT_TRUE(listener.wait_for_line(std::regex("^HEARD pulse [0-9]+$"), 0ms)) << listener.output();

  ChildProcess echo(cli({"run", "tinyline", "echo", "--dds", "-r", "input:=/ros_chatter", "--no-table"}));
  ChildProcess talker(
      peer({"pub", "--type", "string", "--topic", "/ros_chatter", "--count", "600", "--period", "0.1"}));
  ASSERT_TRUE(echo.wait_for_line(std::regex("^data: \"tinyline interop [0-9]+: grüße\"$"), kDiscovery + 30s))
      << echo.output() << talker.output();
  EXPECT_TRUE(echo.find("remote publisher in a participant that is not tinyline connected")) << echo.output();
}

TEST(Ros2Discovery, ANodeOnRmwCycloneddsDefaultsFindsUsToo) {
  REQUIRE_ROS2_SANDBOX();
  // ROS 2's other middleware: Jazzy's rmw_cyclonedds_cpp runs Cyclone DDS
  // 0.10, as we do, and sets it up for ROS 2's default range this way
  // (multicast on one card, participant index auto, at most 32; its
  // check_create_domain). A tinyline process with exactly that configuration
  // plays the ROS 2 node, both ways.
  const std::vector<std::string> rmw_subnet = {
      "CYCLONEDDS_URI=<CycloneDDS><Domain><Discovery><ParticipantIndex>auto</ParticipantIndex>"
      "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>"};
  ChildProcess ours(
      cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/cyclone/ours", "-p", "rate_hz:=20", "--no-table"}));
  ChildProcess theirs(cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/cyclone/theirs", "-p", "rate_hz:=20",
                           "--name", "rmw_pulse", "--no-table"}),
                      rmw_subnet);
  ChildProcess their_echo(cli({"run", "tinyline", "echo", "--dds", "-r", "input:=/cyclone/ours", "--no-table"}),
                          rmw_subnet);
  ChildProcess our_echo(cli({"run", "tinyline", "echo", "--dds", "-r", "input:=/cyclone/theirs", "--no-table"}));
  EXPECT_TRUE(their_echo.wait_for_line(std::regex("^data: \"pulse [0-9]+\"$"), kDiscovery)) << their_echo.output();
  EXPECT_TRUE(our_echo.wait_for_line(std::regex("^data: \"pulse [0-9]+\"$"), kDiscovery)) << our_echo.output();
}

TEST(Ros2Discovery, NothingLeavesTheMachineByDefault) {
  REQUIRE_ROS2_SANDBOX();
  // Two tinyline processes with the defaults talk; the card sends nothing:
  // no multicast, no group membership reports, no unicast to other hosts.
  auto tx = [] {  // the card's transmitted packets, from this namespace's /proc/net/dev
    std::ifstream f("/proc/net/dev");
    for (std::string line; std::getline(f, line);) {
      std::istringstream in(line);
      std::string name;
      in >> name;
      if (name != "nic0:") continue;
      long v = 0;
      for (int i = 0; i < 10; ++i) in >> v;  // 8 receive counters, transmitted bytes, packets
      return v;
    }
    return -1L;
  };
  const long before = tx();
  ASSERT_GE(before, 0);
  {
    ChildProcess echo(cli({"run", "tinyline", "echo", "--dds", "-r", "input:=/local", "--no-table"}));
    ChildProcess pulse(
        cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/local", "-p", "rate_hz:=50", "--no-table"}));
    ASSERT_TRUE(echo.wait_for_count("data: \"pulse", 20, kDiscovery)) << echo.output() << pulse.output();
  }
  EXPECT_EQ(tx(), before) << "packets went out of the network card";
}

TEST(Ros2Discovery, Ros2DiscoveryVariablesSetForBothSidesConnectThemAsTheySay) {
  REQUIRE_ROS2_SANDBOX();
  // What a ROS 2 user exports in a shell holds for tinyline as for the ROS 2
  // node started from it.
  const std::vector<std::vector<std::string>> settings = {
      {"ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST"},
      {"ROS_STATIC_PEERS=127.0.0.1"},
      {"ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET"},
      {"ROS_LOCALHOST_ONLY=1"},
      {"ROS_DOMAIN_ID=7", "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST"},
  };
  for (const auto& env : settings) {
    SCOPED_TRACE(fmt::format("{}", fmt::join(env, " ")));
    ChildProcess pulse(
        cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/env_chatter", "-p", "rate_hz:=20", "--no-table"}),
        env);
    ChildProcess listener(peer({"sub", "--type", "string", "--topic", "/env_chatter", "--count", "2", "--any"}), env);
    EXPECT_TRUE(exited_ok(listener, kDiscovery + 30s)) << listener.output() << pulse.output();
    if (env[0] == "ROS_LOCALHOST_ONLY=1") {
      EXPECT_TRUE(pulse.wait_for_text("ROS_LOCALHOST_ONLY is deprecated", 0ms)) << pulse.output();
    }
  }
}

TEST(Ros2Discovery, DifferentDomainsAndDiscoveryOffKeepGraphsApart) {
  REQUIRE_ROS2_SANDBOX();
  // Control: a default process on the same topic name, which the ROS 2 node
  // must see; the two others it must not.
  ChildProcess seen(cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/apart_seen", "--no-table"}));
  ChildProcess other_domain(cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/apart", "--no-table"}),
                            {"ROS_DOMAIN_ID=3"});
  ChildProcess off(cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/apart", "--no-table"}),
                   {"ROS_AUTOMATIC_DISCOVERY_RANGE=OFF"});
  ChildProcess control(peer({"endpoints", "--topic", "/apart_seen", "--count", "1"}));
  ASSERT_TRUE(exited_ok(control, kDiscovery + 30s)) << control.output() << seen.output();
  // Three of our announcement periods after the control was found, nothing
  // of the other two: a bound on a negative, not a wait for success.
  ChildProcess apart(peer({"endpoints", "--topic", "/apart", "--count", "1", "--timeout", "8"}));
  const auto st = apart.wait_exit(60s);
  ASSERT_TRUE(st.has_value());
  EXPECT_NE(WEXITSTATUS(*st), 0) << apart.output();
  EXPECT_FALSE(apart.find("ENDPOINT")) << apart.output();
}

// ------------------------------------------------------------------ messages and QoS

TEST(Ros2Client, TheLaserDemosScansReachADefaultRos2Subscriber) {
  REQUIRE_ROS2_SANDBOX();
  // The newcomer's first try: the shipped demo as it is, and what
  // `ros2 topic echo /laser/laser_scan` subscribes with.
  const std::string bag = fmt::format("{}/tl_ros2_demo_{}.mcap", ::testing::TempDir(), getpid());
  ChildProcess demo(cli(
      {"launch", std::string(TINYLINE_SOURCE_DIR) + "/launch/laser_demo.launch.yaml", "bag:=" + bag, "--no-table"}));
  ChildProcess echo(peer({"sub", "--type", "laser_scan", "--topic", "/laser/laser_scan", "--count", "5", "--any"}));
  ASSERT_TRUE(exited_ok(echo, kDiscovery + 60s)) << echo.output() << demo.output();
  const auto lines = echo.lines();
  for (const auto& l : lines) {
    if (l.rfind("HEARD", 0) != 0) continue;
    // 256 pixels of the simulated sensor, its frame, its limits.
    const std::regex scan(R"(^HEARD frame=laser_scan ranges=256 in_range=[0-9]+ angles=-0\.[0-9]+\.\.0\.[0-9]+ )"
                          R"(limits=0\.050\.\.3\.000$)");
    EXPECT_TRUE(std::regex_search(l, scan)) << l;
  }
  EXPECT_EQ(count_lines(echo, "HEARD "), 5u) << echo.output();
  std::filesystem::remove(bag);
}

TEST(Ros2Client, EveryMirroredStandardTypeRoundTripsFieldForFieldThroughATinylineProcess) {
  REQUIRE_ROS2_SANDBOX();
  // rclpy sends; tinyline decodes into its C++ types and encodes again; rclpy
  // compares what came back with what it sent, every field.
  ChildProcess relays(cli({"launch", kHere + "launch/relays.launch.yaml", "--no-table"}));
  for (const std::string type : {"string", "laser_scan", "point_cloud2", "diagnostic_array", "marker_array"}) {
    SCOPED_TRACE(type);
    ChildProcess rt(peer({"roundtrip", "--type", type, "--out", "/ros2/" + type + "/in", "--back",
                          "/ros2/" + type + "/out", "--count", "5"}));
    EXPECT_TRUE(exited_ok(rt, kDiscovery + 60s)) << rt.output() << relays.output();
    EXPECT_TRUE(rt.find("ROUNDTRIP OK 5")) << rt.output();
  }
  EXPECT_FALSE(relays.find("does not decode")) << relays.output();
}

TEST(Ros2Client, ReliablePairsDeliverEveryMessageInOrderBothWays) {
  REQUIRE_ROS2_SANDBOX();
  Graph g;
  // Deep queues on both sides: a burst of 20 must not push out unread ones.
  auto pub = g.node->create_publisher<StringMsg>("/reliable/to_ros", bus::QoS::keep_last(100));
  tlt::Inbox<std::string> in(g.signal);
  auto sub = g.node->create_subscription<StringMsg>("/reliable/from_ros", bus::QoS::keep_last(50),
                                                    [&](const StringMsg& m) { in.push(m.data); });
  g.run();
  ChildProcess ros_sub(peer({"sub", "--topic", "/reliable/to_ros", "--count", "20", "--depth", "100"}));
  ASSERT_TRUE(ros_sub.wait_for_text("READY", kDiscovery)) << ros_sub.output();
  ASSERT_TRUE(g.bridge->wait_for_peers({{"/reliable/to_ros", 1, 0}}, kDiscovery).ok) << g.sink->dump();
  for (int i = 1; i <= 20; ++i) pub->publish(numbered(i));
  ASSERT_TRUE(exited_ok(ros_sub, kDiscovery)) << ros_sub.output();
  EXPECT_EQ(got(ros_sub), one_to(20));

  // A volatile reader takes what is written after it matched the writer:
  // rclpy publishes once both sides matched (the go file says ours did).
  const std::string go = fmt::format("{}/tl_ros2_go_{}", ::testing::TempDir(), getpid());
  std::filesystem::remove(go);
  ChildProcess ros_pub(peer(
      {"pub", "--topic", "/reliable/from_ros", "--count", "20", "--depth", "100", "--go-file", go, "--linger", "10"}));
  ASSERT_TRUE(g.bridge->wait_for_peers({{"/reliable/from_ros", 0, 1}}, kDiscovery).ok) << g.sink->dump();
  std::ofstream(go).put('\n');
  ASSERT_TRUE(g.signal->wait_for([&] { return in.size() >= 20; }, kDiscovery)) << ros_pub.output() << g.sink->dump();
  std::filesystem::remove(go);
  std::vector<std::string> want;
  for (int i = 1; i <= 20; ++i) want.push_back(numbered(i)->data);
  EXPECT_EQ(in.items(), want);
}

TEST(Ros2Client, SensorDataPairsAreBestEffortBothWays) {
  REQUIRE_ROS2_SANDBOX();
  // The driver's case: a sensor_data() publisher and a SensorDataQoS
  // subscriber, in both directions, as between two ROS 2 nodes.
  Graph g;
  auto pub = g.node->create_publisher<sensor_msgs::msg::LaserScan>("/sensor/to_ros", bus::QoS::sensor_data());
  tlt::Inbox<std::uint32_t> in(g.signal);
  auto sub = g.node->create_subscription<StringMsg>("/sensor/from_ros", bus::QoS::sensor_data(),
                                                    [&](const StringMsg&) { in.push(1); });
  g.run();
  ChildProcess ros_sub(peer(
      {"sub", "--type", "laser_scan", "--topic", "/sensor/to_ros", "--count", "5", "--qos", "sensor_data", "--any"}));
  ASSERT_TRUE(ros_sub.wait_for_text("READY", kDiscovery)) << ros_sub.output();
  ASSERT_TRUE(g.bridge->wait_for_peers({{"/sensor/to_ros", 1, 0}}, kDiscovery).ok) << g.sink->dump();
  // Best effort may drop; a stream until five arrived is the behaviour.
  for (int i = 0; i < 2000 && !ros_sub.wait_exit(5ms); ++i) {
    auto m = std::make_unique<sensor_msgs::msg::LaserScan>();
    m->header.frame_id = "laser";
    m->range_min = 0.05f;
    m->range_max = 2.0f;
    m->ranges.assign(256, 1.0f);
    pub->publish(std::move(m));
  }
  const auto lines = ros_sub.lines();
  EXPECT_EQ(
      std::count_if(lines.begin(), lines.end(),
                    [](const std::string& l) { return l.rfind("HEARD frame=laser ranges=256 in_range=256", 0) == 0; }),
      5)
      << ros_sub.output();
  const auto links = g.bridge->stats();
  for (const auto& l : links) EXPECT_EQ(l.incompatible, 0u) << l.topic;

  ChildProcess ros_pub(
      peer({"pub", "--topic", "/sensor/from_ros", "--qos", "sensor_data", "--count", "200", "--period", "0.02"}));
  EXPECT_TRUE(g.signal->wait_for([&] { return in.size() >= 5; }, kDiscovery)) << ros_pub.output() << g.sink->dump();
}

TEST(Ros2Client, LatchedTopicsReachLateJoinersOnEitherSide) {
  REQUIRE_ROS2_SANDBOX();
  Graph g;
  auto pub = g.node->create_publisher<StringMsg>("/latched/from_tinyline", bus::QoS::keep_last(1).latched());
  g.run();
  pub->publish(numbered(1));
  // A ROS 2 subscriber that starts after the message was published.
  ChildProcess late_ros(peer({"sub", "--topic", "/latched/from_tinyline", "--qos", "latched", "--count", "1"}));
  ASSERT_TRUE(exited_ok(late_ros, kDiscovery + 30s)) << late_ros.output() << g.sink->dump();
  EXPECT_EQ(got(late_ros), one_to(1));

  // A ROS 2 latched publisher, then a tinyline subscription made afterwards.
  ChildProcess ros_pub(peer({"pub", "--topic", "/latched/from_ros", "--qos", "latched", "--count", "1", "--wait-subs",
                             "0", "--linger", "60"}));
  ASSERT_TRUE(ros_pub.wait_for_text("DONE", kDiscovery)) << ros_pub.output();
  tlt::Inbox<std::string> in(g.signal);
  bus::NodeOptions no;
  no.name = "late_joiner";
  no.context = g.ctx;
  auto late = std::make_shared<bus::Node>(no);
  auto sub = late->create_subscription<StringMsg>("/latched/from_ros", bus::QoS::keep_last(1).latched(),
                                                  [&](const StringMsg& m) { in.push(m.data); });
  g.ex->add_node(late);
  ASSERT_TRUE(g.signal->wait_for([&] { return in.size() >= 1; }, kDiscovery)) << g.sink->dump();
  EXPECT_EQ(in.items(), std::vector<std::string>{numbered(1)->data});
}

TEST(Ros2Client, IncompatibleQosIsRefusedOnBothSidesAsBetweenTwoRos2Nodes) {
  REQUIRE_ROS2_SANDBOX();
  Graph g;
  auto pub = g.node->create_publisher<StringMsg>("/mismatch/volatile");
  auto sub =
      g.node->create_subscription<StringMsg>("/mismatch/best_effort", bus::QoS::keep_last(10), [](const StringMsg&) {});
  g.run();
  // A latched ROS 2 subscriber cannot take a volatile publisher...
  ChildProcess ros_sub(
      peer({"sub", "--topic", "/mismatch/volatile", "--qos", "latched", "--count", "1", "--timeout", "30"}));
  EXPECT_TRUE(ros_sub.wait_for_text("INCOMPATIBLE DURABILITY", kDiscovery)) << ros_sub.output();
  EXPECT_TRUE(g.logged(bus::LogLevel::Warn, "durability (volatile vs transient local)", kDiscovery)) << g.sink->dump();
  // ...nor a reliable subscriber a best-effort ROS 2 publisher.
  ChildProcess ros_pub(peer({"pub", "--topic", "/mismatch/best_effort", "--qos", "sensor_data", "--count", "1",
                             "--wait-subs", "0", "--linger", "30"}));
  EXPECT_TRUE(ros_pub.wait_for_text("INCOMPATIBLE RELIABILITY", kDiscovery)) << ros_pub.output();
  EXPECT_TRUE(g.logged(bus::LogLevel::Warn, "reliability (best effort vs reliable)", kDiscovery)) << g.sink->dump();
}

TEST(Ros2Client, AKilledRos2NodeIsNoticedAndARestartedOneReconnects) {
  REQUIRE_ROS2_SANDBOX();
  Graph g;
  tlt::Inbox<std::string> in(g.signal);
  auto sub = g.node->create_subscription<StringMsg>("/beat", bus::QoS::keep_last(100),
                                                    [&](const StringMsg& m) { in.push(m.data); });
  g.run();
  const std::vector<std::string> beat =
      peer({"pub", "--topic", "/beat", "--count", "100000", "--period", "0.05", "--timeout", "600"});
  {
    ChildProcess first(beat);
    ASSERT_TRUE(g.signal->wait_for([&] { return in.size() >= 3; }, kDiscovery)) << first.output() << g.sink->dump();
    first.signal(SIGKILL);
    ASSERT_TRUE(first.wait_exit(10s));
  }
  // Noticed when the killed node's lease runs out.
  ASSERT_TRUE(
      g.logged(bus::LogLevel::Warn, "/beat: lost the remote publisher in a participant that is not tinyline", kLease))
      << g.sink->dump();
  const std::size_t before = in.size();
  ChildProcess second(beat);
  ASSERT_TRUE(g.signal->wait_for([&] { return in.size() >= before + 3; }, kDiscovery))
      << second.output() << g.sink->dump();
  EXPECT_TRUE(g.sink->contains(bus::LogLevel::Info,
                               "/beat: remote publisher in a participant that is not tinyline "
                               "connected"));
  // What arrives now is the restarted node's: messages it says it sent, in order.
  const auto items = in.items();
  for (std::size_t k = before; k < before + 3; ++k) {
    const std::string index = items[k].substr(std::string("tinyline interop ").size());
    // Its line may still be on the way through the pipe when the message is here.
    EXPECT_TRUE(second.wait_for_line(std::regex("^SENT " + index.substr(0, index.find(':')) + "$"), 10s))
        << items[k] << "\n"
        << second.output();
    if (k > before) {
      EXPECT_EQ(std::stoi(index), std::stoi(items[k - 1].substr(17)) + 1) << items[k];
    }
  }
}

TEST(Ros2Client, AKilledTinylineProcessIsNoticedByTheRos2Node) {
  REQUIRE_ROS2_SANDBOX();
  ChildProcess pulse(cli({"run", "tinyline", "pulse", "--dds", "-r", "output:=/gone", "--no-table"}));
  ChildProcess watch(peer({"endpoints", "--topic", "/gone", "--count", "1"}));
  ASSERT_TRUE(exited_ok(watch, kDiscovery + 30s)) << watch.output() << pulse.output();
  pulse.signal(SIGKILL);
  ASSERT_TRUE(pulse.wait_exit(10s));
  // Our 3 s lease: the graph of a fresh ROS 2 node no longer has the writer.
  std::string last;
  for (const auto deadline = std::chrono::steady_clock::now() + 30s; std::chrono::steady_clock::now() < deadline;) {
    ChildProcess again(peer({"endpoints", "--topic", "/gone", "--count", "1", "--timeout", "5"}));
    again.wait_exit(60s);
    last = again.output();
    if (!again.find("ENDPOINT")) break;
  }
  EXPECT_EQ(last.find("ENDPOINT"), std::string::npos) << last;
}

TEST(Ros2Client, Ros2SeesOurEndpointsWithTheirTypeAndTypeHash) {
  REQUIRE_ROS2_SANDBOX();
  Graph g;
  auto pub = g.node->create_publisher<sensor_msgs::msg::LaserScan>("/typed", bus::QoS::sensor_data());
  g.run();
  ChildProcess info(peer({"endpoints", "--topic", "/typed", "--count", "1"}));
  ASSERT_TRUE(exited_ok(info, kDiscovery + 30s)) << info.output();
  EXPECT_TRUE(info.find(fmt::format("ENDPOINT pub sensor_msgs/msg/LaserScan {} RELIABLE VOLATILE",
                                    msg::type_support<sensor_msgs::msg::LaserScan>().type_hash)))
      << info.output();
}

// ------------------------------------------------------------------ graph citizenship

namespace {

std::vector<std::string> graph_watcher(std::vector<std::string> args) {
  args.insert(args.begin(), {TINYLINE_VENV_PYTHON, kHere + "ros2_graph.py"});
  return args;
}

std::string venv_prefix() { return std::filesystem::path(TINYLINE_VENV_PYTHON).parent_path().parent_path().string(); }

/// The environment that lets rclpy import a package built into `install`.
std::vector<std::string> with_package(const std::string& install) {
  return {"PYTHONPATH=" + install + "/lib/python3.11/site-packages", "LD_LIBRARY_PATH=" + install + "/lib",
          "AMENT_PREFIX_PATH=" + install + ":" + venv_prefix()};
}

}  // namespace

TEST(Ros2Graph, ADefaultRos2NodeInANamespaceSeesEveryNodeOfTheDemoItsLogItsParametersAndTheSensorFrames) {
  REQUIRE_ROS2_SANDBOX();
  // No wheel ships tf2_msgs: rosidl builds TFMessage for rclpy from our mirror
  // (its hash is checked against a Jazzy system's in Ros2TypeHashes).
  const std::string work = std::string(TINYLINE_BINARY_DIR) + "/test/ros2/tf2_msgs_ws";
  ChildProcess build({"/bin/bash", kHere + "build_interface_package.sh", venv_prefix(), TINYLINE_SOURCE_DIR, work,
                      "test/ros2/tf2_msgs"});
  ASSERT_TRUE(exited_ok(build, 540s)) << build.output();

  // The watcher first: parameter declarations go out once a subscriber is there.
  ChildProcess watcher(graph_watcher({"--node",    "/laser/laser",
                                      "--node",    "/sim/scene",
                                      "--node",    "/recorder",
                                      "--node",    "/laser_scan_frame",
                                      "--pub",     "/laser/laser=/laser/laser_scan",
                                      "--pub",     "/laser/laser=/rosout",
                                      "--pub",     "/laser_scan_frame=/tf_static",
                                      "--owner",   "/laser/laser_scan=/laser/laser",
                                      "--log",     "laser.laser=port ",
                                      "--param",   "/laser/laser=frame_id",
                                      "--frame",   "laser=laser_scan",
                                      "--timeout", "90"}),
                       with_package(work + "/install"));
  const std::string bag = fmt::format("{}/tl_ros2_graph_{}.mcap", ::testing::TempDir(), getpid());
  ChildProcess demo(cli(
      {"launch", std::string(TINYLINE_SOURCE_DIR) + "/launch/laser_demo.launch.yaml", "bag:=" + bag, "--no-table"}));
  ASSERT_TRUE(exited_ok(watcher, kDiscovery + 90s)) << watcher.output() << demo.output();
  // ALL SEEN includes rclpy naming /laser/laser as the owner of its scans
  // (between discovering an endpoint and the process's ros_discovery_info it
  // says _NODE_NAME_UNKNOWN_, as it does for a ROS 2 node's).
  EXPECT_TRUE(watcher.find("ALL SEEN")) << watcher.output();
  // T_laser_laserscan of docs/driver.md, as the shipped launch file declares it.
  EXPECT_TRUE(watcher.find("FRAME laser laser_scan 0 0 0 -0.5 -0.5 -0.5 0.5")) << watcher.output();
  EXPECT_TRUE(watcher.wait_for_line(std::regex("^PARAM /laser/laser frame_id 'laser'$"), 0ms)) << watcher.output();
  std::filesystem::remove(bag);
}

TEST(Ros2Graph, ANodeRunAloneIsListedWithItsPublishersAndSubscriptionsNotAsUnknown) {
  REQUIRE_ROS2_SANDBOX();
  ChildProcess watcher(graph_watcher({"--node", "/tl/relay", "--pub", "/tl/relay=/out", "--sub", "/tl/relay=/in",
                                      "--owner", "/out=/tl/relay", "--param", "/tl/relay=type", "--timeout", "60"}));
  ChildProcess relay(cli({"run", "tinyline", "relay", "--dds", "--name", "relay", "--ns", "/tl", "-r", "input:=/in",
                          "-r", "output:=/out", "--no-table"}));
  ASSERT_TRUE(exited_ok(watcher, kDiscovery + 60s)) << watcher.output() << relay.output();
  EXPECT_TRUE(watcher.find("ALL SEEN")) << watcher.output();
  EXPECT_TRUE(watcher.find("PUB /tl/relay /out std_msgs/msg/String")) << watcher.output();
}

TEST(Ros2Client, TheDriverOffersTheLineAsPointCloud2) {
  REQUIRE_ROS2_SANDBOX();
  const std::string scene = std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/wrench_panel.yaml";
  ChildProcess driver(cli({"run", "tiny_laser_driver", "laser_driver", "--dds", "--name", "laser", "--ns", "/laser",
                           "-p", "port:=sim:" + scene, "-p", "mode:=raw", "-p", "publish_cloud:=true", "--no-table"}));
  ChildProcess echo(peer({"sub", "--type", "point_cloud2", "--topic", "/laser/cloud", "--count", "3", "--any"}));
  ASSERT_TRUE(exited_ok(echo, kDiscovery + 60s)) << echo.output() << driver.output();
  // One point per pixel, x y z intensity float32, NaN where no distance.
  const std::regex cloud(
      R"(^HEARD frame=laser height=1 width=272 fields=x:0:7:1,y:4:7:1,z:8:7:1,intensity:12:7:1 point_step=16 )"
      R"(row_step=4352 dense=False valid=([0-9]+) z_max=([0-9.]+)$)");
  std::size_t clouds = 0;
  for (const auto& l : echo.lines()) {
    if (l.rfind("HEARD", 0) != 0) continue;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(l, m, cloud)) << l;
    EXPECT_GT(std::stoi(m[1]), 100) << l;  // the panel fills most of the line
    EXPECT_LT(std::stod(m[2]), 3.0) << l;  // within the sensor's reach
    ++clouds;
  }
  EXPECT_EQ(clouds, 3u) << echo.output();
}

// ------------------------------------------------------------------ type hashes and the interface package

namespace {

/// Every generated type's "name hash" line, as type_hashes.py reads them.
std::string write_our_hashes(const std::string& path, const std::string& only_pkg = "") {
  std::ofstream f(path);
  for (const auto* ts : msg::all_type_supports()) {
    const bool ours = ts->name.rfind("tinyline_msgs/", 0) == 0;
    if (only_pkg.empty() ? !ours : ts->name.rfind(only_pkg + "/", 0) == 0)
      f << ts->name << " " << ts->type_hash << "\n";
  }
  return path;
}

}  // namespace

TEST(Ros2TypeHashes, EveryMirroredStandardTypeHashesAsTheRos2WheelsShipIt) {
  if (access(TINYLINE_VENV_PYTHON, X_OK) != 0) GTEST_SKIP() << "no test venv at " << TINYLINE_VENV_PYTHON;
  // The independent proof that a mirrored type is ROS 2's, field for field:
  // its hash equals the hash_string of the type description rosidl shipped.
  const std::string ours = write_our_hashes(fmt::format("{}/tl_hashes_{}.txt", ::testing::TempDir(), getpid()));
  std::size_t standard = 0;
  for (const auto* ts : msg::all_type_supports()) standard += ts->name.rfind("tinyline_msgs/", 0) == 0 ? 0 : 1;
  ChildProcess check({TINYLINE_VENV_PYTHON, kHere + "type_hashes.py", ours, venv_prefix() + "/share", "--require",
                      "builtin_interfaces", "std_msgs", "geometry_msgs", "sensor_msgs", "diagnostic_msgs",
                      "visualization_msgs", "rosgraph_msgs", "rmw_dds_common", "rcl_interfaces"});
  EXPECT_TRUE(exited_ok(check, 120s)) << check.output();
  // tf2_msgs: no wheel; below.
  EXPECT_EQ(count_lines(check, "OK "), standard - 1) << check.output();
  EXPECT_TRUE(check.find("NO REFERENCE tf2_msgs/msg/TFMessage")) << check.output();
  EXPECT_GE(standard, 30u);
  std::filesystem::remove(ours);
}

TEST(Ros2TypeHashes, TfMessageHashesAsAJazzySystemReportsIt) {
  // The registry has no tf2_msgs wheel; this is the hash `ros2 topic info -v
  // /tf_static` prints on ROS 2 Jazzy. Its fields (TransformStamped, Header,
  // Transform, ...) are each checked against the wheels above.
  EXPECT_EQ(msg::type_support<tf2_msgs::msg::TFMessage>().type_hash,
            "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087");
}

TEST(Ros2InterfacePackage, AWorkspaceBuildsTinylineMsgsFromOurMsgFilesAndExchangesThemWithUs) {
  REQUIRE_ROS2_SANDBOX();
  // msg/ros2/tinyline_msgs built as a ROS 2 workspace builds it (ament_cmake,
  // rosidl_generate_interfaces over our .msg files) with the wheels' tools.
  const std::string work = std::string(TINYLINE_BINARY_DIR) + "/test/ros2/tinyline_msgs_ws";
  ChildProcess build({"/bin/bash", kHere + "build_interface_package.sh", venv_prefix(), TINYLINE_SOURCE_DIR, work});
  ASSERT_TRUE(exited_ok(build, 540s)) << build.output();
  const std::string install = work + "/install";

  // rosidl's hashes of our types are the ones our generator computed.
  const std::string ours =
      write_our_hashes(fmt::format("{}/tl_own_hashes_{}.txt", ::testing::TempDir(), getpid()), "tinyline_msgs");
  ChildProcess check(
      {TINYLINE_VENV_PYTHON, kHere + "type_hashes.py", ours, install + "/share", "--require", "tinyline_msgs"});
  EXPECT_TRUE(exited_ok(check, 120s)) << check.output();
  // Every one of our .msg files.
  std::size_t ours_count = 0;
  for (const auto& f : std::filesystem::directory_iterator(std::string(TINYLINE_SOURCE_DIR) + "/msg/msg/tinyline_msgs"))
    ours_count += f.path().extension() == ".msg";
  EXPECT_GE(ours_count, 17u);
  EXPECT_EQ(count_lines(check, "OK "), ours_count) << check.output();
  std::filesystem::remove(ours);

  // A ROS 2 node using the built package exchanges LineScans with tinyline.
  ChildProcess relay(cli({"run", "tinyline", "relay", "--dds", "-p", "type:=tinyline_msgs/msg/LineScan", "-r",
                          "input:=/ros2/line_scan/in", "-r", "output:=/ros2/line_scan/out", "--no-table"}));
  const std::vector<std::string> env = with_package(install);
  ChildProcess rt(peer({"roundtrip", "--type", "line_scan", "--out", "/ros2/line_scan/in", "--back",
                        "/ros2/line_scan/out", "--count", "5"}),
                  env);
  EXPECT_TRUE(exited_ok(rt, kDiscovery + 60s)) << rt.output() << relay.output();
  EXPECT_TRUE(rt.find("ROUNDTRIP OK 5")) << rt.output();
}
