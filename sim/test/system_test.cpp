// SPDX-License-Identifier: Apache-2.0
// A SimulatedSystem shares one scene among its sensors: who emits when is
// recorded, so one sensor's sets catch another's light only while that one
// emits (the host's sequence mode, Algorithm 4, relies on it).
#include <gtest/gtest.h>

#include <sim/system.hpp>

using namespace tinyline::sim;

namespace {

// Two sensors 5 cm apart, side by side, facing one wall 80 cm away.
Scene two_sensors() {
  const std::string yaml = R"(
name: pair
objects:
  - {name: wall, shape: plane, material: wall_paint, pose: {xyz: [0, 0, 0.8]}}
sensors:
  - {name: left, pose: {xyz: [0, 0, 0]}, params: {effects: []}}
  - {name: right, pose: {xyz: [0.05, 0, 0]}, params: {effects: []}}
)";
  return load_scene_string(yaml, "pair.yaml", ".");
}

}  // namespace

TEST(SimulatedSystem, CrosstalkFollowsTheOtherSensorsEmission) {
  SystemOptions o;
  o.clock_ppm_sd = 0.0;  // identical pulse clocks: in step for the whole set
  SimulatedSystem sys(two_sensors(), o);
  ASSERT_EQ(sys.sensor_count(), 2u);
  const std::vector<int> sched{20, 100, 200, 400, 700};

  // Only the left sensor emits: no crosstalk.
  sys.set_emitting(0, true, 1.0);
  const SensorSet alone = sys.measure(0, 1.0, sched, 1);
  EXPECT_EQ(alone.crosstalk_pulses, 0);

  // The right sensor's pulse train starts with ours: every pulse of our set
  // catches its light, and the pixels collect more charge.
  sys.set_emitting(1, true, 1.0);
  const SensorSet both = sys.measure(0, 1.0, sched, 1);
  EXPECT_EQ(both.crosstalk_pulses, 700);
  const std::size_t c = 136;
  // (100 pulses: the 700-pulse read-out of a wall at 80 cm is near full scale.)
  EXPECT_GT(both.readouts[1].a[c] + both.readouts[1].b[c], 1.2 * (alone.readouts[1].a[c] + alone.readouts[1].b[c]));

  // The host switches the right sensor's laser off (sequence mode): a later
  // set of ours is clean again, and the earlier record does not leak into it.
  sys.set_emitting(1, false, 1.5);
  const SensorSet after = sys.measure(0, 2.0, sched, 2);
  EXPECT_EQ(after.crosstalk_pulses, 0);
  // Switched off half way through our set: only the pulses before catch it.
  sys.set_emitting(1, true, 3.0);
  sys.set_emitting(1, false, 3.0 + 350.0 / 25000.0);
  const SensorSet half = sys.measure(0, 3.0, sched, 3);
  EXPECT_NEAR(half.crosstalk_pulses, 350, 2);
}

TEST(SimulatedSystem, UnknownSensorNamesTheKnownOnes) {
  SimulatedSystem sys(two_sensors());
  try {
    (void)sys.sensor_index("middle");
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("left, right"), std::string::npos) << e.what();
  }
  EXPECT_EQ(sys.sensor_index("right"), 1u);
}
