// SPDX-License-Identifier: Apache-2.0
// The one set of checks for numbers on every program's command line.
#include <gtest/gtest.h>

#include <tinyline/common/cli.hpp>

namespace c = tinyline::cli;

namespace {
// What the check says about `text`: "" when it passes.
std::string check(const c::Validator& v, std::string text) { return v(text); }
}  // namespace

TEST(CliNumbers, FiniteRefusesNanInfinityAndText) {
  EXPECT_EQ(check(c::finite(), "-3.5"), "");
  EXPECT_EQ(check(c::finite(), "nan"), "'nan' is not a finite number");
  EXPECT_EQ(check(c::finite(), "-inf"), "'-inf' is not a finite number");
  EXPECT_EQ(check(c::finite(), "ten"), "'ten' is not a number");
  EXPECT_EQ(check(c::finite(), ""), "'' is not a number");
}

TEST(CliNumbers, PositiveAndNonNegativeNameTheBound) {
  EXPECT_EQ(check(c::positive(), "0.001"), "");
  EXPECT_EQ(check(c::positive(), "0"), "0 must be greater than 0");
  EXPECT_EQ(check(c::non_negative(), "0"), "");
  EXPECT_EQ(check(c::non_negative(), "-1"), "-1 must be at least 0");
  EXPECT_EQ(check(c::seconds(), "-1"), "-1 must be greater than 0");
  EXPECT_EQ(check(c::finite_above(0.1, true, 10.0), "10.5"), "10.5 must be at most 10");
}

TEST(CliNumbers, WholeNumbersStayInTheirRange) {
  EXPECT_EQ(check(c::threads(), "256"), "");
  EXPECT_EQ(check(c::threads(), "0"), "0 is outside 1..256");
  EXPECT_EQ(check(c::threads(), "2.5"), "'2.5' is not a whole number");
  EXPECT_EQ(check(c::count(), "-1"), "-1 must be at least 0");
  EXPECT_EQ(check(c::count(), "99999999999999999999"), "99999999999999999999 must be at least 0");
}

TEST(CliParse, HelpIsExitZeroAndABadNumberExitTwo) {
  double d = 0.0;
  c::App app("test");
  app.add_option("--d", d)->check(c::positive());
  const char* help[] = {"prog", "--help"};
  testing::internal::CaptureStdout();
  EXPECT_EQ(c::parse_command_line(app, 2, const_cast<char**>(help)), 0);
  EXPECT_NE(testing::internal::GetCapturedStdout().find("Usage: "), std::string::npos);
  c::App app2("test");
  app2.add_option("--d", d)->check(c::positive());
  const char* bad[] = {"prog", "--d", "nan"};
  testing::internal::CaptureStderr();
  EXPECT_EQ(c::parse_command_line(app2, 3, const_cast<char**>(bad)), 2);
  EXPECT_NE(testing::internal::GetCapturedStderr().find("--d: 'nan' is not a finite number"), std::string::npos);
  const char* good[] = {"prog", "--d", "2"};
  c::App app3("test");
  app3.add_option("--d", d)->check(c::positive());
  EXPECT_EQ(c::parse_command_line(app3, 3, const_cast<char**>(good)), std::nullopt);
  EXPECT_EQ(d, 2.0);
}
