// SPDX-License-Identifier: Apache-2.0
// The supervisor's start gate: a gated child says it is ready, is held until
// the gates open, and its ready line is not forwarded; a child restarted
// after the gates opened goes through at once.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "../src/supervisor.hpp"

using namespace tinyline::tools;
using namespace std::chrono_literals;

namespace {

std::string contents(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string s;
  char buf[512];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof(buf), f)) > 0;) s.append(buf, n);
  std::fseek(f, 0, SEEK_END);
  return s;
}

/// Polls until `pred` holds or the hang guard expires.
template <class P>
bool poll_until(Supervisor& s, P pred) {
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    s.poll(20ms);
  }
  return true;
}

ChildSpec gated_child(const std::string& name, const std::string& script) {
  ChildSpec c;
  c.name = name;
  c.gated = true;
  c.argv = {"/bin/sh", "-c", script};
  return c;
}

}  // namespace

TEST(SupervisorStartGate, ChildrenWaitUntilEveryOneIsReadyAndTheGatesOpen) {
  std::FILE* out = std::tmpfile();
  std::FILE* err = std::tmpfile();
  ASSERT_TRUE(out && err);
  SupervisorOptions o;
  o.out = out;
  o.err = err;
  Supervisor s(o);
  const std::string ready(kReadyLine);
  s.start(gated_child("a", "echo '" + ready + "'; read go; echo \"a started after $go\""));
  // b is ready only when told (a file appears), so a is held meanwhile.
  const std::string flag = ::testing::TempDir() + "/tl_gate_" + std::to_string(getpid());
  std::remove(flag.c_str());
  s.start(gated_child("b", "while [ ! -e " + flag + " ]; do sleep 0.01; done; echo '" + ready +
                               "'; read go; echo \"b started after $go\""));
  ASSERT_TRUE(poll_until(s, [&] { return s.not_ready() == std::vector<std::string>{"b"}; }));
  EXPECT_FALSE(s.all_ready());
  std::FILE* f = std::fopen(flag.c_str(), "w");
  ASSERT_TRUE(f);
  std::fclose(f);
  ASSERT_TRUE(poll_until(s, [&] { return s.all_ready(); }));
  EXPECT_EQ(contents(out).find("started"), std::string::npos) << "a child started before the gates opened";
  s.open_gates();
  ASSERT_TRUE(poll_until(s, [&] { return s.running() == 0; })) << contents(out) << contents(err);
  const std::string text = contents(out);
  EXPECT_NE(text.find("[a] a started after go\n"), std::string::npos) << text;
  EXPECT_NE(text.find("[b] b started after go\n"), std::string::npos) << text;
  EXPECT_EQ(text.find(ready), std::string::npos) << "the ready line is the supervisor's, not output";
  std::remove(flag.c_str());
  std::fclose(out);
  std::fclose(err);
}

TEST(SupervisorStartGate, AChildStartedAfterTheGatesOpenedGoesThroughAtOnce) {
  std::FILE* out = std::tmpfile();
  std::FILE* err = std::tmpfile();
  SupervisorOptions o;
  o.out = out;
  o.err = err;
  Supervisor s(o);
  s.open_gates();
  s.start(gated_child("late", "echo '" + std::string(kReadyLine) + "'; read go; echo \"late started after $go\""));
  ASSERT_TRUE(poll_until(s, [&] { return s.running() == 0; })) << contents(err);
  EXPECT_NE(contents(out).find("[late] late started after go\n"), std::string::npos) << contents(out);
  std::fclose(out);
  std::fclose(err);
}
