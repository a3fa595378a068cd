// SPDX-License-Identifier: Apache-2.0
// The graph across processes over DDS, driven through the real command line:
// tinyline launch with process groups, tinyline topic, killing and restarting
// processes. Every test runs on its own DDS domain and tag.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <regex>

#include <fmt/format.h>

#include <tinyline/dds/settings.hpp>
#ifdef TINYLINE_DDS_PIPELINE_TEST
#include <cmath>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>
#endif

#include "child_process.hpp"

using namespace std::chrono_literals;
using tinyline::testing::ChildProcess;

namespace {

const std::string kLaunchDir = std::string(TINYLINE_SOURCE_DIR) + "/test/dds/launch/";

/// A DDS domain and tag of this test alone, for every process it starts.
std::vector<std::string> dds_env() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string tag = fmt::format("{}_{}", info ? info->name() : "t", getpid());
  return {fmt::format("ROS_DOMAIN_ID={}", 1 + getpid() % 200), "CYCLONEDDS_URI=" + tinyline::dds::loopback_config(tag)};
}

std::vector<std::string> cli(std::vector<std::string> args) {
  args.insert(args.begin(), TINYLINE_EXE);
  return args;
}

/// The `data:` values the echo nodes printed (from one process's log lines).
std::vector<std::string> echoed(const std::vector<std::string>& lines, const std::string& prefix = "") {
  std::vector<std::string> out;
  const std::regex re("^" + prefix + "data: \"(.*)\"$");
  for (const auto& l : lines) {
    std::smatch m;
    if (std::regex_match(l, m, re)) out.push_back(m[1]);
  }
  return out;
}

std::vector<std::string> pulses(int n) {
  std::vector<std::string> v;
  for (int i = 1; i <= n; ++i) v.push_back("pulse " + std::to_string(i));
  return v;
}

/// Stops a launch with Ctrl-C and checks it ends cleanly.
void interrupt_and_expect_clean_exit(ChildProcess& p) {
  p.signal(SIGINT);
  const auto st = p.wait_exit(30s);
  ASSERT_TRUE(st.has_value()) << "launch did not stop after SIGINT\n" << p.output();
  EXPECT_TRUE(WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << "status " << *st << "\n" << p.output();
}

}  // namespace

TEST(MultiProcess, ThreeProcessesOverDdsPrintWhatOneProcessPrints) {
  const auto env = dds_env();
  // 20 Hz: the relay's and echo's queues of 10 ride out a half-second stall.
  const int n = 30;
  std::vector<std::string> one, three;
  {
    ChildProcess p(cli({"launch", kLaunchDir + "chain.launch.yaml", "source_process:=", "relay_process:=",
                        fmt::format("count:={}", n), "rate_hz:=20", "--no-table"}),
                   env);
    ASSERT_TRUE(p.wait_for_text(fmt::format("data: \"pulse {}\"", n), 30s)) << p.output();
    interrupt_and_expect_clean_exit(p);
    one = echoed(p.lines());
    EXPECT_EQ(p.find("[launch] started process"), std::nullopt) << "one process expected";
  }
  {
    ChildProcess p(
        cli({"launch", kLaunchDir + "chain.launch.yaml", fmt::format("count:={}", n), "rate_hz:=20", "--no-table"}),
        env);
    ASSERT_TRUE(p.wait_for_text(fmt::format("data: \"pulse {}\"", n), 30s)) << p.output();
    ASSERT_TRUE(p.find("[launch] started process 'source'"));
    ASSERT_TRUE(p.find("[launch] started process 'relay'"));
    interrupt_and_expect_clean_exit(p);
    three = echoed(p.lines());
    // The split really went over DDS: the relay process received what it relayed.
    EXPECT_TRUE(p.wait_for_line(std::regex(fmt::format(R"(^\[relay\] /chain/raw +[0-9]+ +[0-9]+ +0 +{} )", n)), 1s))
        << p.output();
  }
  EXPECT_EQ(one, pulses(n));
  EXPECT_EQ(three, one);
}

TEST(MultiProcess, AKilledProcessIsReportedAndARestartedPublisherIsRediscovered) {
  ChildProcess p(cli({"launch", kLaunchDir + "loss.launch.yaml", "--no-table", "--respawn-delay", "0.2"}), dds_env());
  ASSERT_TRUE(p.wait_for_text("[sink] data: \"pulse 3\"", 30s)) << p.output();
  ASSERT_TRUE(p.wait_for_line(std::regex("^data: \"pulse 3\""), 30s)) << p.output();
  std::smatch m;
  auto started = [&](const std::string& name) {
    const auto line = p.wait_for_line(std::regex("started process '" + name + R"(' \(pid [0-9]+\))"), 1s);
    EXPECT_TRUE(line) << p.output();
    std::regex_search(*line, m, std::regex(R"(pid ([0-9]+))"));
    return static_cast<pid_t>(std::stoi(m[1]));
  };
  const pid_t sink = started("sink");
  const pid_t source = started("source");

  // The sink dies for good: the supervisor says so, the source reports the
  // lost subscriber, and the graph goes on.
  kill(sink, SIGKILL);
  ASSERT_TRUE(p.wait_for_text(
      fmt::format("[launch] process 'sink' (pid {}; nodes /remote_echo) was killed by signal 9", sink), 10s))
      << p.output();
  EXPECT_TRUE(p.find("the others keep running"));
  ASSERT_TRUE(p.wait_for_text(fmt::format("lost the remote subscriber in process 'sink' (pid {}", sink), 15s))
      << p.output();
  const std::size_t after_sink = p.lines().size();
  ASSERT_TRUE(p.wait_for_line(std::regex("^data: \"pulse"), 10s, after_sink)) << "local echo stopped\n" << p.output();

  // The source dies and is restarted: the launching process reports the lost
  // publisher, finds the new one and hears it from its first message on.
  kill(source, SIGKILL);
  ASSERT_TRUE(p.wait_for_text(fmt::format("[launch] process 'source' (pid {}; nodes /source) was killed by signal 9 "
                                          "(Killed); restarting in 0.2 s",
                                          source),
                              10s))
      << p.output();
  const auto restarted = p.wait_for_line(std::regex(R"(\[launch\] restarted process 'source' \(pid [0-9]+\))"), 10s);
  ASSERT_TRUE(restarted) << p.output();
  const std::size_t at_restart = *p.find("[launch] restarted process 'source'");
  ASSERT_TRUE(p.wait_for_line(std::regex("^data: \"pulse 1\""), 15s, at_restart)) << p.output();
  ASSERT_TRUE(p.wait_for_text(fmt::format("lost the remote publisher in process 'source' (pid {}", source), 15s))
      << p.output();
  // The restart did not wait for the dead sink: it rejoined with the peers still there.
  EXPECT_TRUE(p.find("[source] [INFO]", at_restart) &&
              p.wait_for_text("rejoined the running graph with the peers still there (/loss/beat: 1 of 2 remote "
                              "subscriber(s)",
                              1s, at_restart))
      << p.output();
  EXPECT_EQ(p.find("starting without every DDS peer"), std::nullopt) << p.output();
  EXPECT_EQ(p.find("[launch] process 'sink'", *p.find("[launch] process 'sink'") + 1), std::nullopt)
      << "the sink (no respawn) was restarted";
  interrupt_and_expect_clean_exit(p);
}

TEST(TopicTools, ListEchoAndHzSeeARunningMultiProcessGraph) {
  const auto env = dds_env();
  ChildProcess graph(cli({"launch", kLaunchDir + "chain.launch.yaml", "count:=0", "rate_hz:=20", "--no-table"}), env);
  ASSERT_TRUE(graph.wait_for_line(std::regex("^data: \"pulse [0-9]+\"$"), 30s)) << graph.output();

  // Discovery takes its time on a loaded machine: list again until both
  // processes' endpoints are in (a deadline, not a sleep).
  const std::regex raw_line(R"(^/chain/raw +std_msgs/msg/String +1 +1 +relay, source$)");
  const std::regex relayed_line(R"(^/chain/relayed +std_msgs/msg/String +1 +1 +chain, relay$)");
  std::string listed;
  for (const auto deadline = std::chrono::steady_clock::now() + 30s; std::chrono::steady_clock::now() < deadline;) {
    ChildProcess list(cli({"topic", "list"}), env);
    ASSERT_TRUE(list.wait_exit(30s)) << list.output();
    listed = list.output();
    if (list.wait_for_line(raw_line, 0ms) && list.wait_for_line(relayed_line, 0ms)) break;
  }
  EXPECT_TRUE(std::regex_search(listed, std::regex(R"((^|\n)/chain/raw +std_msgs/msg/String +1 +1 +relay, source\n)")))
      << listed;
  EXPECT_TRUE(
      std::regex_search(listed, std::regex(R"((^|\n)/chain/relayed +std_msgs/msg/String +1 +1 +chain, relay\n)")))
      << listed;

  ChildProcess echo(cli({"topic", "echo", "/chain/relayed", "--count", "3"}), env);
  const auto st = echo.wait_exit(30s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << echo.output();
  const auto got = echoed(echo.lines());
  ASSERT_EQ(got.size(), 3u) << echo.output();
  const int first = std::stoi(got[0].substr(6));
  EXPECT_EQ(got, (std::vector<std::string>{got[0], "pulse " + std::to_string(first + 1),
                                           "pulse " + std::to_string(first + 2)}));
  EXPECT_EQ(echo.lines().size(), 6u) << "three YAML documents, '---' after each\n" << echo.output();

  ChildProcess hz(cli({"topic", "hz", "/chain/raw", "--duration", "2.5"}), env);
  ASSERT_TRUE(hz.wait_exit(30s)) << hz.output();
  // The last report covers the whole run. The pulse's wall-clock timer runs
  // late and catches up on a loaded machine (or under TSan), so the band is
  // wide; it still catches a period reported as a rate, or every message
  // counted twice.
  std::string rate_line;
  for (const auto& l : hz.lines())
    if (l.rfind("average rate: ", 0) == 0) rate_line = l;
  ASSERT_FALSE(rate_line.empty()) << hz.output();
  const double rate = std::stod(rate_line.substr(14));
  EXPECT_GT(rate, 12.0) << hz.output();
  EXPECT_LT(rate, 32.0) << hz.output();

  ChildProcess missing(cli({"topic", "echo", "/chain/nothing", "--wait", "0.5"}), env);
  const auto mst = missing.wait_exit(30s);
  ASSERT_TRUE(mst);
  EXPECT_EQ(WEXITSTATUS(*mst), 1);
  EXPECT_TRUE(missing.wait_for_text("no publisher of /chain/nothing appeared within 0.5 s", 1s)) << missing.output();
  interrupt_and_expect_clean_exit(graph);
}

namespace {

/// Runs the two-hosts launch file in two network namespaces, each host's DDS
/// set up as `mode` says (two_hosts.sh), and checks the graph spans them.
void run_two_hosts(const std::string& mode) {
  const std::string work = fmt::format("{}/tl_two_hosts_{}_{}", ::testing::TempDir(), mode, getpid());
  std::filesystem::remove_all(work);
  std::filesystem::create_directories(work);
  ChildProcess p({"/bin/bash", std::string(TINYLINE_SOURCE_DIR) + "/test/dds/two_hosts.sh", TINYLINE_EXE,
                  kLaunchDir + "two_hosts.launch.yaml", work, mode});
  const auto first = p.wait_for_line(std::regex("^(SKIP: .*|veth up: .*)$"), 30s);
  if (first && first->rfind("SKIP: ", 0) == 0) GTEST_SKIP() << *first;
  ASSERT_TRUE(first) << p.output();
  ASSERT_TRUE(p.wait_for_text("[host_b] data: \"pulse 20\"", 60s)) << p.output();
  // Each host started from the same file with --process, waited for its peer
  // on the other side of the cable, and the first message made it across.
  EXPECT_EQ(echoed(p.lines(), R"(\[host_b\] )"), pulses(20)) << p.output();
  EXPECT_TRUE(p.find("[host_b] [INFO]") && p.find("remote publisher in process 'host_a'")) << p.output();
  std::filesystem::remove_all(work);
}

}  // namespace

TEST(MultiHost, TwoNetworkNamespacesJoinedByAVethPairRunOneGraph) { run_two_hosts("uri"); }

TEST(MultiHost, Ros2StaticPeersNamingTheOtherHostJoinTwoNamespaces) {
  // ROS_STATIC_PEERS alone, as a ROS 2 user sets it: this machine plus the
  // other one, by unicast.
  run_two_hosts("static_peers");
}

TEST(TopicTools, ASingleNodeStartedWithRunDdsJoinsALaunchedGraph) {
  const auto env = dds_env();
  ChildProcess graph(cli({"launch", kLaunchDir + "chain.launch.yaml", "count:=0", "rate_hz:=20", "--no-table"}), env);
  ASSERT_TRUE(graph.wait_for_line(std::regex("^data: \"pulse [0-9]+\"$"), 30s)) << graph.output();
  ChildProcess node(
      cli({"run", "tinyline", "echo", "--name", "visitor", "-r", "input:=/chain/raw", "--dds", "--no-table"}), env);
  ASSERT_TRUE(node.wait_for_line(std::regex("^data: \"pulse [0-9]+\"$"), 30s)) << node.output();
  EXPECT_TRUE(node.find("remote publisher in process 'source'")) << node.output();
  interrupt_and_expect_clean_exit(node);
  interrupt_and_expect_clean_exit(graph);
}

#ifdef TINYLINE_DDS_PIPELINE_TEST
namespace {

/// A bag of `n` raw scans (tinyline_msgs/RawScan on /tiny/raw, 5 Hz) of a
/// scene the K sensor's public calibration turns into ranges: a wall at about
/// 1.2 m, a bright object near 0.45 m that moves a pixel per scan, a dimmer one
/// near 0.8 m; every read-out level as the sensor sends it (the top ones
/// saturate on the bright object), a little deterministic noise.
void write_raw_bag(const std::string& path, int n) {
  namespace bag = tinyline::bag;
  bag::ros2::Ros2Writer w;
  ASSERT_TRUE(w.open(path).ok());
  bag::ChannelId ch = 0;
  ASSERT_TRUE(w.add_topic("/tiny/raw", tinyline::msg::type_support<tinyline::tinyline_msgs::msg::RawScan>(), ch).ok());
  constexpr std::uint16_t kPulses[5] = {20, 100, 200, 400, 700};
  constexpr int kPixels = 272;
  for (int s = 0; s < n; ++s) {
    tinyline::tinyline_msgs::msg::RawScan m;
    const std::int64_t t_ns = 1'000'000'000'000LL + s * 200'000'000LL;
    m.header.stamp.sec = static_cast<std::int32_t>(t_ns / 1'000'000'000);
    m.header.stamp.nanosec = static_cast<std::uint32_t>(t_ns % 1'000'000'000);
    m.header.frame_id = "tiny";
    m.set_index = static_cast<std::uint32_t>(s);
    m.temperature_c = 44.0f;  // the K calibration's stable temperature: no offset
    m.pixels = kPixels;
    m.pulses.assign(std::begin(kPulses), std::end(kPulses));
    m.a.resize(5 * kPixels);
    m.b.resize(5 * kPixels);
    for (int p = 0; p < kPixels; ++p) {
      double k = 0.72, per_pulse = 0.15;  // charge ratio b/(a+b), charge per pulse [charge unit]
      if (p >= 60 + s && p < 100 + s) k = 0.56, per_pulse = 0.5;
      if (p >= 170 && p < 185) k = 0.63, per_pulse = 0.3;
      k += 0.003 * std::sin(1.7 * p + 0.9 * s);
      for (int i = 0; i < 5; ++i) {
        const double sum = std::min(per_pulse * kPulses[i], 480.0);
        m.a[static_cast<std::size_t>(i * kPixels + p)] = static_cast<std::int16_t>(std::lround(10.0 * sum * (1.0 - k)));
        m.b[static_cast<std::size_t>(i * kPixels + p)] = static_cast<std::int16_t>(std::lround(10.0 * sum * k));
      }
    }
    ASSERT_TRUE(w.write(ch, m, static_cast<bag::Timestamp>(t_ns), static_cast<bag::Timestamp>(t_ns),
                        static_cast<std::uint32_t>(s + 1))
                    .ok());
  }
  ASSERT_TRUE(w.close().ok());
}

/// The YAML of every message the echo node `sink` printed, one string each.
std::vector<std::string> echoed_messages(const std::vector<std::string>& lines, const std::string& topic) {
  std::vector<std::string> out;
  const std::string start = "[/sink]: " + topic + ":";
  std::string* cur = nullptr;
  for (const auto& l : lines) {
    if (l.size() >= start.size() && l.compare(l.size() - start.size(), start.size(), start) == 0) {
      out.emplace_back();
      cur = &out.back();
    } else if (cur != nullptr && l == "---") {
      cur = nullptr;
    } else if (cur != nullptr) {
      *cur += l + "\n";
    }
  }
  return out;
}

}  // namespace

TEST(MultiProcess, DriverAndClusteringInTwoProcessesGiveWhatOneProcessGivesOnAReplayedBag) {
  const auto env = dds_env();
  // 5 Hz: the clusterer's queue of 5 scans rides out a one-second stall of a
  // loaded machine (the nodes keep the last N, as they would live).
  const int n = 12;
  const std::string work = fmt::format("{}/tl_pipeline_{}", ::testing::TempDir(), getpid());
  std::filesystem::create_directories(work);
  const std::string bag_path = work + "/raw.mcap";
  write_raw_bag(bag_path, n);
  const std::string launch_file = kLaunchDir + "driver_clustering.launch.yaml";
  const std::string sink_start = "[/sink]: /tiny/clusters:";

  std::vector<std::string> one, two;
  {
    ChildProcess p(
        cli({"launch", launch_file, "bag:=" + bag_path, "driver_process:=", "clustering_process:=", "--no-table"}),
        env);
    ASSERT_TRUE(p.wait_for_count(sink_start, n, 60s)) << p.output();
    interrupt_and_expect_clean_exit(p);
    EXPECT_EQ(p.find("[launch] started process"), std::nullopt) << "one process expected";
    one = echoed_messages(p.lines(), "/tiny/clusters");
  }
  {
    ChildProcess p(cli({"launch", launch_file, "bag:=" + bag_path, "--no-table"}), env);
    ASSERT_TRUE(p.wait_for_count(sink_start, n, 60s)) << p.output();
    ASSERT_TRUE(p.find("[launch] started process 'driver'"));
    ASSERT_TRUE(p.find("[launch] started process 'clustering'"));
    interrupt_and_expect_clean_exit(p);
    two = echoed_messages(p.lines(), "/tiny/clusters");
    // The scans crossed from the driver's process to the clusterer's over DDS
    // (every one of them), and the clusters came back to this one.
    EXPECT_TRUE(p.wait_for_line(std::regex(fmt::format(R"(^\[driver\] /tiny/scan +[0-9]+ +[0-9]+ +{} +0 )", n)), 1s))
        << p.output();
    EXPECT_TRUE(
        p.wait_for_line(std::regex(fmt::format(R"(^\[clustering\] /tiny/scan +[0-9]+ +[0-9]+ +0 +{} )", n)), 1s))
        << p.output();
    EXPECT_TRUE(p.wait_for_line(std::regex(fmt::format(R"(^/tiny/clusters +[0-9]+ +[0-9]+ +0 +{} )", n)), 1s))
        << p.output();
  }
  ASSERT_EQ(one.size(), static_cast<std::size_t>(n));
  // Not an empty comparison: the scans hold objects and the clusterer found them.
  std::size_t with_clusters = 0;
  for (const auto& m : one) with_clusters += m.find("clusters:\n") != std::string::npos ? 1 : 0;
  EXPECT_EQ(with_clusters, static_cast<std::size_t>(n)) << one.front();
  ASSERT_EQ(two.size(), one.size());
  for (std::size_t i = 0; i < one.size(); ++i) EXPECT_EQ(two[i], one[i]) << "message " << i;
  std::filesystem::remove_all(work);
}
#endif
