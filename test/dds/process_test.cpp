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

#include "child_process.hpp"

using namespace std::chrono_literals;
using tinyline::testing::ChildProcess;

namespace {

const std::string kLaunchDir = std::string(TINYLINE_SOURCE_DIR) + "/test/dds/launch/";

/// A DDS domain and tag of this test alone, for every process it starts.
std::vector<std::string> dds_env() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string tag = fmt::format("{}_{}", info ? info->name() : "t", getpid());
  return {fmt::format("ROS_DOMAIN_ID={}", 1 + getpid() % 200),
          "CYCLONEDDS_URI=" + tinyline::dds::loopback_config(tag)};
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
  const int n = 40;
  std::vector<std::string> one, three;
  {
    ChildProcess p(cli({"launch", kLaunchDir + "chain.launch.yaml", "source_process:=", "relay_process:=",
                             fmt::format("count:={}", n), "--no-table"}),
                   env);
    ASSERT_TRUE(p.wait_for_text(fmt::format("data: \"pulse {}\"", n), 30s)) << p.output();
    interrupt_and_expect_clean_exit(p);
    one = echoed(p.lines());
    EXPECT_EQ(p.find("[launch] started process"), std::nullopt) << "one process expected";
  }
  {
    ChildProcess p(cli({"launch", kLaunchDir + "chain.launch.yaml", fmt::format("count:={}", n), "--no-table"}),
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
  ChildProcess p(cli({"launch", kLaunchDir + "loss.launch.yaml", "--no-table", "--respawn-delay", "0.2"}),
                 dds_env());
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
  ASSERT_TRUE(p.wait_for_text(fmt::format("[launch] process 'sink' (pid {}; nodes /remote_echo) was killed by signal 9",
                                          sink),
                              10s))
      << p.output();
  EXPECT_TRUE(p.find("the others keep running"));
  ASSERT_TRUE(p.wait_for_text(fmt::format("lost the remote subscriber in process 'sink' (pid {}", sink), 15s))
      << p.output();
  const std::size_t after_sink = p.lines().size();
  ASSERT_TRUE(p.wait_for_line(std::regex("^data: \"pulse"), 10s, after_sink)) << "local echo stopped\n"
                                                                               << p.output();

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
  EXPECT_EQ(p.find("[launch] process 'sink'", *p.find("[launch] process 'sink'") + 1), std::nullopt)
      << "the sink (no respawn) was restarted";
  interrupt_and_expect_clean_exit(p);
}

TEST(TopicTools, ListEchoAndHzSeeARunningMultiProcessGraph) {
  const auto env = dds_env();
  ChildProcess graph(cli({"launch", kLaunchDir + "chain.launch.yaml", "count:=0", "rate_hz:=20", "--no-table"}),
                     env);
  ASSERT_TRUE(graph.wait_for_text("data: \"pulse 2\"", 30s)) << graph.output();

  ChildProcess list(cli({"topic", "list"}), env);
  ASSERT_TRUE(list.wait_exit(30s)) << list.output();
  EXPECT_TRUE(list.wait_for_line(std::regex(R"(^/chain/raw +std_msgs/msg/String +1 +1 +relay, source$)"), 1s))
      << list.output();
  EXPECT_TRUE(list.wait_for_line(std::regex(R"(^/chain/relayed +std_msgs/msg/String +1 +1 +chain, relay$)"), 1s))
      << list.output();

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
  // The last report covers the whole run (the first second may start with
  // two samples that arrive together as the reader joins).
  std::string rate_line;
  for (const auto& l : hz.lines())
    if (l.rfind("average rate: ", 0) == 0) rate_line = l;
  ASSERT_FALSE(rate_line.empty()) << hz.output();
  EXPECT_NEAR(std::stod(rate_line.substr(14)), 20.0, 1.0) << hz.output();

  ChildProcess missing(cli({"topic", "echo", "/chain/nothing", "--wait", "0.5"}), env);
  const auto mst = missing.wait_exit(30s);
  ASSERT_TRUE(mst);
  EXPECT_EQ(WEXITSTATUS(*mst), 1);
  EXPECT_TRUE(missing.wait_for_text("no publisher of /chain/nothing appeared within 0.5 s", 1s)) << missing.output();
  interrupt_and_expect_clean_exit(graph);
}

TEST(MultiHost, TwoNetworkNamespacesJoinedByAVethPairRunOneGraph) {
  const std::string work = fmt::format("{}/tl_two_hosts_{}", ::testing::TempDir(), getpid());
  std::filesystem::remove_all(work);
  std::filesystem::create_directories(work);
  ChildProcess p({"/bin/bash", std::string(TINYLINE_SOURCE_DIR) + "/test/dds/two_hosts.sh", TINYLINE_EXE,
                  kLaunchDir + "two_hosts.launch.yaml", work});
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

TEST(TopicTools, ASingleNodeStartedWithRunDdsJoinsALaunchedGraph) {
  const auto env = dds_env();
  ChildProcess graph(cli({"launch", kLaunchDir + "chain.launch.yaml", "count:=0", "rate_hz:=20", "--no-table"}), env);
  ASSERT_TRUE(graph.wait_for_text("data: \"pulse 1\"", 30s)) << graph.output();
  ChildProcess node(cli({"run", "tinyline", "echo", "--name", "visitor", "-r", "input:=/chain/raw", "--dds",
                         "--no-table"}),
                    env);
  ASSERT_TRUE(node.wait_for_line(std::regex("^data: \"pulse [0-9]+\"$"), 30s)) << node.output();
  EXPECT_TRUE(node.find("remote publisher in process 'source'")) << node.output();
  interrupt_and_expect_clean_exit(node);
  interrupt_and_expect_clean_exit(graph);
}
