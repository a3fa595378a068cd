// The simulator's nodes on the bus, stepped on sim time by the deterministic
// executor (no sleeps).
#include <gtest/gtest.h>

#include <cmath>

#include <tinyline/bus/testing.hpp>

#include "sim/nodes/nodes.hpp"
#include "sim/nodes/register.hpp"

namespace bus = tinyline::bus;
using namespace tinyline::sim;
using tinyline::tinyline_msgs::msg::RawScan;
using tinyline::tinyline_msgs::msg::ScanTruth;
using tinyline::tinyline_msgs::msg::SceneTruth;

namespace {

std::string scene_path() { return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/calibration_rail.yaml"; }

// The sim nodes on stepped sim time from t = 100 s (bus/testing.hpp), with
// everything they publish kept.
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&register_nodes}, bus::Time::from_seconds(100.0)) {}
  std::vector<std::shared_ptr<const RawScan>>& raw = collect<RawScan>("raw_scan", bus::QoS::keep_last(100));
  std::vector<std::shared_ptr<const ScanTruth>>& truth = collect<ScanTruth>("scan_truth", bus::QoS::keep_last(100));
  std::vector<std::shared_ptr<const SceneTruth>>& objects = collect<SceneTruth>("objects", bus::QoS::keep_last(100));
  std::shared_ptr<bus::Node> add(const std::string& type, bus::NodeOptions o) {
    return NodeRig::add("sim", type, std::move(o));
  }
};

}  // namespace

TEST(SimNodes, VirtualSensorPublishesRawScansAndTheirTruth) {
  Harness h;
  bus::NodeOptions o;
  o.name = "laser";
  o.param("scene", scene_path());
  h.add("virtual_sensor", o);
  h.ex.advance_to(bus::Time::from_seconds(100.3));
  ASSERT_GE(h.raw.size(), 8u);
  ASSERT_EQ(h.truth.size(), h.raw.size());
  const RawScan& r = *h.raw.back();
  EXPECT_EQ(r.header.frame_id, "laser");
  ASSERT_EQ(r.pulses.size(), 5u);
  EXPECT_EQ(r.pulses.back(), 700);
  EXPECT_EQ(r.pixels, 272);
  EXPECT_EQ(r.a.size(), 5u * 272u);
  const ScanTruth& t = *h.truth.back();
  EXPECT_EQ(t.set_index, r.set_index);
  EXPECT_EQ(t.header.stamp.sec, r.header.stamp.sec);
  EXPECT_EQ(t.header.stamp.nanosec, r.header.stamp.nanosec);
  EXPECT_NEAR(t.range_m[136], 0.5, 1e-3);
  EXPECT_EQ(t.objects[static_cast<std::size_t>(t.object[136])], "target");
  EXPECT_EQ(t.materials[static_cast<std::size_t>(t.material[136])], "white_paper");
  EXPECT_TRUE(t.flags[136] & ScanTruth::FLAG_LIT);
  EXPECT_TRUE(t.flags[0] & ScanTruth::FLAG_DARK);
  // The charges are the wire's: the 100-pulse read-out of the centre pixel is
  // about 100 * 6.92 * (0.3/0.5)^2 / 2 per capacitor, times 10.
  const double sum = (r.a[272 + 136] + r.b[272 + 136]) / 10.0;
  EXPECT_NEAR(sum, 100 * 6.92 * 0.36, 40.0);
}

TEST(SimNodes, VirtualSensorIsReproducibleOnSimTime) {
  std::vector<std::int16_t> first;
  for (int run = 0; run < 2; ++run) {
    Harness h;
    bus::NodeOptions o;
    o.name = "laser";
    o.param("scene", scene_path());
    h.add("virtual_sensor", o);
    h.ex.advance_to(bus::Time::from_seconds(100.1));
    ASSERT_FALSE(h.raw.empty());
    if (run == 0) first = h.raw.front()->a;
    else EXPECT_EQ(h.raw.front()->a, first);
  }
}

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

TEST(SimNodes, MissingSceneIsAClearError) {
  Harness h;
  bus::NodeOptions o;
  o.name = "laser";
  h.add("virtual_sensor", o);
  try {
    h.ex.advance_to(bus::Time::from_seconds(100.1));
    FAIL() << "no error without a scene";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'scene' is required"), std::string::npos) << e.what();
  }
}
