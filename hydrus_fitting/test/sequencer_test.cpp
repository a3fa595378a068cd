// SPDX-License-Identifier: Apache-2.0
// The sequencer: interference from geometry, minimum colourings, schedules
// that are safe, their rates against the thesis's time slicing, and
// recomputation as the robot moves.
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "hydrus_fitting/sequencer.hpp"

namespace hf = tinyline::hydrus_fitting;
using ::testing::HasSubstr;

namespace {

constexpr double kPi = std::numbers::pi;
const std::string kConfig = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";

hf::SensorView2D sensor(double x, double y, double yaw_deg, double range = 2.0) {
  hf::SensorView2D s;
  s.origin_m = {x, y};
  s.yaw_rad = yaw_deg * kPi / 180.0;
  s.fov_half_angle_rad = 35.0 * kPi / 180.0;
  s.fan_half_angle_rad = 38.0 * kPi / 180.0;
  s.range_m = range;
  return s;
}

bool valid(const hf::InterferenceGraph& g, const hf::Colouring& c) {
  for (int i = 0; i < g.n; ++i)
    for (int j = 0; j < g.n; ++j)
      if (i != j && g.conflict(i, j) && c.colour[static_cast<std::size_t>(i)] == c.colour[static_cast<std::size_t>(j)])
        return false;
  return true;
}

}  // namespace

TEST(Interference, BackToBackSensorsDoNotConflict) {
  const std::vector<hf::SensorView2D> s{sensor(0, 0, 0), sensor(-0.1, 0, 180)};
  const auto g = hf::interference_graph(s, {});
  EXPECT_EQ(g.edges(), 0);
}

TEST(Interference, FacingOrOverlappingSensorsConflict) {
  const std::vector<hf::SensorView2D> facing{sensor(0, 0, 0), sensor(1, 0, 180)};
  EXPECT_TRUE(hf::interference_graph(facing, {}).conflict(0, 1));
  const std::vector<hf::SensorView2D> side_by_side{sensor(0, 0, 90), sensor(0.3, 0, 90)};
  const auto g = hf::interference_graph(side_by_side, {});
  EXPECT_TRUE(g.conflict(0, 1));
  EXPECT_TRUE(g.conflict(1, 0));  // symmetric
  EXPECT_TRUE(std::isfinite(g.witness_m[1].x()));
  // Out of each other's range: no conflict.
  const std::vector<hf::SensorView2D> far{sensor(0, 0, 90, 0.5), sensor(3, 0, 90, 0.5)};
  EXPECT_EQ(hf::interference_graph(far, {}).edges(), 0);
}

TEST(Interference, AnObjectBetweenTwoSensorsSeparatesThem) {
  // Two sensors on opposite sides of a 0.45 m cylinder, 0.1 m from its
  // surface: it fills both fans (53 deg half angle > 38 + margin), so every
  // ray lands on the near side, which the other sensor cannot see.
  const std::vector<hf::SensorView2D> s{sensor(0, -0.55, 90), sensor(0, 0.55, -90)};
  EXPECT_TRUE(hf::interference_graph(s, {}).conflict(0, 1));
  hf::Occluders occ;
  occ.circles.push_back({{0, 0}, 0.45});
  EXPECT_FALSE(hf::interference_graph(s, occ).conflict(0, 1));
  // A small object leaves rays past it: the conflict stays.
  occ.circles[0].radius_m = 0.05;
  EXPECT_TRUE(hf::interference_graph(s, occ).conflict(0, 1));
}

TEST(Colouring, MinimumColouringsOfKnownGraphs) {
  const std::vector<std::pair<int, int>> c5{{0, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 0}};
  const std::vector<std::pair<int, int>> c6{{0, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 5}, {5, 0}};
  const std::vector<std::pair<int, int>> k4{{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  const std::vector<std::pair<int, int>> none;
  // The Groetzsch graph (11 vertices, triangle-free, chromatic number 4).
  const std::vector<std::pair<int, int>> groetzsch{{0, 1}, {1, 2},  {2, 3},  {3, 4},  {4, 0},  {5, 1}, {5, 4},
                                                   {6, 0}, {6, 2},  {7, 1},  {7, 3},  {8, 2},  {8, 4}, {9, 3},
                                                   {9, 0}, {10, 5}, {10, 6}, {10, 7}, {10, 8}, {10, 9}};
  const struct {
    int n;
    const std::vector<std::pair<int, int>>& e;
    int chromatic;
  } cases[] = {{5, c5, 3}, {6, c6, 2}, {4, k4, 4}, {4, none, 1}, {11, groetzsch, 4}};
  for (const auto& c : cases) {
    const auto g = hf::graph_from_edges(c.n, c.e);
    const auto col = hf::colour_graph(g);
    EXPECT_EQ(col.colours, c.chromatic) << c.n;
    EXPECT_TRUE(col.optimal);
    EXPECT_TRUE(valid(g, col));
  }
  EXPECT_THROW((void)hf::graph_from_edges(3, std::vector<std::pair<int, int>>{{0, 3}}), std::invalid_argument);
}

TEST(Schedule, TimeSlicingDividesTheRateByN) {
  const hf::SlotTiming t{0.01, 0.0};
  const auto s = hf::time_slicing_schedule(4, t);
  ASSERT_EQ(s.slot_count(), 4);
  for (const double r : s.rate_hz) EXPECT_DOUBLE_EQ(r, 25.0);
  EXPECT_TRUE(hf::check_schedule(hf::graph_from_edges(4, std::vector<std::pair<int, int>>{{0, 1}}), s).ok());
}

TEST(Schedule, ColouringScheduleIsSafeAndFillsFreeSlots) {
  // A triangle and a sensor that conflicts with nobody: three slots, and the
  // free sensor emits in all of them (full rate) instead of 1/4.
  const auto g = hf::graph_from_edges(4, std::vector<std::pair<int, int>>{{0, 1}, {1, 2}, {2, 0}});
  const auto col = hf::colour_graph(g);
  const hf::SlotTiming t{0.01, 0.0};
  const auto s = hf::colouring_schedule(g, col, t);
  EXPECT_TRUE(hf::check_schedule(g, s).ok());
  EXPECT_EQ(s.slot_count(), 3);
  EXPECT_NEAR(s.rate_hz[3], 100.0, 1e-9);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(s.rate_hz[static_cast<std::size_t>(i)], 100.0 / 3.0, 1e-9);
  const auto thesis = hf::time_slicing_schedule(4, t);
  for (int i = 0; i < 4; ++i)
    EXPECT_GT(s.rate_hz[static_cast<std::size_t>(i)], thesis.rate_hz[static_cast<std::size_t>(i)]);
  // Without filling, each sensor gets exactly its colour's slot.
  const auto plain = hf::colouring_schedule(g, col, t, false);
  EXPECT_NEAR(plain.rate_hz[3], 100.0 / 3.0, 1e-9);
}

TEST(Schedule, CheckScheduleNamesTheProblem) {
  const auto g = hf::graph_from_edges(3, std::vector<std::pair<int, int>>{{0, 1}});
  hf::Schedule s;
  s.slots = {{0, 1}, {2}};
  EXPECT_THAT(hf::check_schedule(g, s).message, HasSubstr("sensors 0 and 1 conflict"));
  s.slots = {{0}, {1}};
  EXPECT_THAT(hf::check_schedule(g, s).message, HasSubstr("sensor 2 never emits"));
}

TEST(Sequencer, HydrusSquareAroundACylinder) {
  // The closed square (90 degrees at every joint) around a cylinder at its
  // centre: adjacent sensors see each other's light on the cylinder, the
  // opposite ones do not. Two slots: twice the thesis's rate.
  const auto m = hf::RobotModel::load(kConfig);
  hf::Sequencer seq(m);
  const std::vector<double> square{kPi / 2, kPi / 2, kPi / 2};
  EXPECT_TRUE(seq.update(square, hf::Circle{{0.25, 0.25}, 0.12}));
  const auto& g = seq.graph();
  EXPECT_TRUE(g.conflict(0, 1));
  EXPECT_TRUE(g.conflict(1, 2));
  EXPECT_FALSE(g.conflict(0, 2)) << "opposite sensors are separated by the cylinder";
  EXPECT_FALSE(g.conflict(1, 3));
  EXPECT_EQ(seq.colouring().colours, 2);
  EXPECT_TRUE(hf::check_schedule(g, seq.schedule()).ok());
  const auto thesis = hf::time_slicing_schedule(4, seq.params().timing);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(seq.schedule().rate_hz[static_cast<std::size_t>(i)], 2.0 * thesis.rate_hz[static_cast<std::size_t>(i)],
                1e-9);
  }
  // Without the object estimate nothing blocks the light across the square.
  hf::Sequencer blind(m);
  (void)blind.update(square, std::nullopt);
  EXPECT_EQ(blind.colouring().colours, 4);
}

TEST(Sequencer, RecomputesOnlyWhenTheRobotMoves) {
  const auto m = hf::RobotModel::load(kConfig);
  hf::Sequencer seq(m);
  std::vector<double> q{kPi / 2, kPi / 2, kPi / 2};
  const hf::Circle object{{0.25, 0.25}, 0.12};
  (void)seq.update(q, object);
  EXPECT_EQ(seq.rebuilds(), 1);
  q[0] += 0.001;  // well under the thresholds
  EXPECT_FALSE(seq.update(q, object));
  EXPECT_EQ(seq.rebuilds(), 1);
  // Open the chain straight: the sensors now look the same way side by side.
  const std::vector<double> straight{0.0, 0.0, 0.0};
  EXPECT_TRUE(seq.update(straight, std::nullopt));
  EXPECT_EQ(seq.rebuilds(), 2);
  EXPECT_TRUE(hf::check_schedule(seq.graph(), seq.schedule()).ok());
}
