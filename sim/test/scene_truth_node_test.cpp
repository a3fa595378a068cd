// SPDX-License-Identifier: Apache-2.0
// The scene_truth node on the bus, stepped on sim time by the deterministic
// executor (no sleeps).

#include "node_rig.hpp"

TEST(SimNodes, SceneTruthPublishesObjectsAndDeviceSets) {
  Harness h;
  bus::NodeOptions o;
  o.name = "scene";
  o.param("scene", scene_path());
  o.param("rate_hz", 20.0);
  auto node = h.add("scene_truth", o);
  h.ex.advance_to(bus::Time::from_seconds(100.2));
  ASSERT_GE(h.objects.size(), 3u);
  const SceneTruth& s = *h.objects.back();
  EXPECT_EQ(s.scene, "calibration_rail");
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[0].name, "target");
  EXPECT_EQ(s.objects[0].shape, "plane");
  EXPECT_NEAR(s.objects[0].pose.position.z, 0.5, 1e-12);
  ASSERT_EQ(s.annotation_keys.size(), 1u);
  EXPECT_EQ(s.annotation_keys[0], "target_distance_m");
  EXPECT_DOUBLE_EQ(s.annotation_values[0], 0.5);
  // A device of this scene in the same process (the driver's sim: port) measures a set.
  auto sys = SimulatedSystem::shared(scene_path());
  const std::vector<int> sched{100};
  sys->notify(0, sys->measure(0, 1.0, sched, 42));
  h.ex.advance_to(bus::Time::from_seconds(100.25));
  ASSERT_EQ(h.truth.size(), 1u);
  EXPECT_EQ(h.truth[0]->set_index, 42u);
  EXPECT_EQ(h.truth[0]->sensor, "laser");
}
