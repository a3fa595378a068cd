// SPDX-License-Identifier: Apache-2.0
// The virtual_sensor node on the bus, stepped on sim time by the deterministic
// executor (no sleeps).

#include "node_rig.hpp"

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
    if (run == 0)
      first = h.raw.front()->a;
    else
      EXPECT_EQ(h.raw.front()->a, first);
  }
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

// The scene is an input file, checked when the node is built: a missing one,
// a FIFO or a device stops a launch (and `launch --check`) at the line that
// set it, before any node starts.
TEST(SimNodes, AMissingOrOddSceneStopsTheNodeWhenBuiltAtTheLineThatSetIt) {
  for (const std::string type : {"virtual_sensor", "scene_truth"}) {
    for (const std::string scene : {"/nonexistent/scene.yaml", "/dev/zero"}) {
      Harness h;
      bus::NodeOptions o;
      o.name = "laser";
      o.params.push_back({"scene", scene, bus::SourceLocation{"rig.launch.yaml", 7, 9}});
      try {
        h.add(type, o);
        ADD_FAILURE() << type << " accepted scene " << scene;
      } catch (const bus::ParamError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.rfind("rig.launch.yaml:7:9: ", 0), 0u) << what;
        EXPECT_NE(what.find("parameter 'scene': file '" + scene + "'"), std::string::npos) << what;
      }
    }
  }
}
