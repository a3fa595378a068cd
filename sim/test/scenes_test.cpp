// SPDX-License-Identifier: Apache-2.0
// The shipped task scenes have the property they exist for.
#include <gtest/gtest.h>

#include <cmath>

#include <sim/fidelity.hpp>
#include <sim/scene.hpp>
#include <sim/tof_sensor.hpp>

using namespace tinyline::sim;

namespace {

std::string scene(const std::string& name) { return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/" + name; }

struct View {
  std::vector<PixelTruth> truth;
  PulseCharges pc;
  SensorSet set;
};

View look(const Scene& s) {
  const TofLineSensor sensor(s.sensors.at(0).params);
  View v;
  v.pc = sensor.pulse_charges(s.world, s.sensors[0].T_world_sensor, 3600.0, &v.truth);
  v.set = sensor.measure(s.world, s.sensors[0].T_world_sensor, 3600.0, sensor.params().acquisition.raw_pulses, 1);
  return v;
}

double per_pulse(const View& v, std::size_t i) { return v.pc.qa[i] + v.pc.qb[i]; }

}  // namespace

TEST(Scenes, WrenchOutshinesThePanelAtAlmostTheSameDistance) {
  const Scene s = load_scene(scene("wrench_panel.yaml"));
  const View v = look(s);
  const ObjectId handle = *s.world.find("wrench_handle"), panel = *s.world.find("panel");
  double wrench = 0, board = 0, wrench_range = 0, board_range = 0;
  int nw = 0, nb = 0;
  for (std::size_t i = 8; i < 264; ++i) {
    if (v.truth[i].mixed) continue;
    if (v.truth[i].object == handle) {
      wrench += per_pulse(v, i);
      wrench_range += v.truth[i].range_m;
      ++nw;
    } else if (v.truth[i].object == panel && std::abs(static_cast<int>(i) - 136) < 60) {
      board += per_pulse(v, i);
      board_range += v.truth[i].range_m;
      ++nb;
    }
  }
  ASSERT_GT(nw, 5);
  ASSERT_GT(nb, 20);
  EXPECT_GT(wrench / nw, 5.0 * board / nb);
  EXPECT_LT(std::abs(wrench_range / nw - board_range / nb), 0.02);
  EXPECT_EQ(s.truth.at("wrench_handle_x_m").size(), 2u);
  // The wrench's pixels still measure (not saturated) at the short read-outs.
  int valid = 0;
  for (std::size_t i = 8; i < 264; ++i)
    if (v.truth[i].object == handle && select_readout(v.set, static_cast<int>(i)) >= 0) ++valid;
  EXPECT_GT(valid, nw / 2);
}

TEST(Scenes, StickNearBackgroundDiffersInReflectanceNotDistance) {
  const Scene near = load_scene(scene("stick_near_background.yaml"));
  const Scene far = load_scene(scene("stick_far_background.yaml"));
  for (const Scene* s : {&near, &far}) {
    const View v = look(*s);
    const ObjectId stick = *s->world.find("stick");
    std::vector<std::size_t> on;
    for (std::size_t i = 8; i < 264; ++i)
      if (v.truth[i].object == stick) on.push_back(i);
    ASSERT_GE(on.size(), 3u) << s->name;
    const std::size_t mid = on[on.size() / 2];
    const std::size_t bg = mid + 30;
    const double gap = v.truth[bg].range_m - v.truth[mid].range_m;
    if (s == &near) {
      EXPECT_LT(gap, 0.012);
    } else {
      EXPECT_GT(gap, 0.09);
    }
    // Reflectance normalised by distance^2: the stick returns several times the board.
    const double rs = per_pulse(v, mid) * v.truth[mid].range_m * v.truth[mid].range_m;
    const double rb = per_pulse(v, bg) * v.truth[bg].range_m * v.truth[bg].range_m;
    EXPECT_GT(rs, 2.0 * rb) << s->name;
  }
}
