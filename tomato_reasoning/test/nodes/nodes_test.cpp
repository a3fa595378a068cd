// The harvesting pipeline on the bus, as launch/tomato_harvest.launch.yaml
// wires it: truss_camera -> tomato_detector -> pick_verifier -> hand_laser ->
// laser_clustering pedicel_finder -> pick_verifier, stepped by the
// deterministic executor on sim time (no sleeps).
#include <cmath>
#include <cstring>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include <laser_clustering/nodes/register.hpp>

#include "tomato_reasoning/nodes/nodes.hpp"
#include "tomato_reasoning/nodes/register.hpp"

namespace bus = tinyline::bus;
namespace tr = tinyline::tomato_reasoning;
using tinyline::sensor_msgs::msg::PointCloud2;
using tinyline::tinyline_msgs::msg::PickVerification;
using tinyline::tinyline_msgs::msg::TomatoEstimates;
using tinyline::visualization_msgs::msg::MarkerArray;

namespace {

// The tomato_reasoning and laser_clustering nodes on stepped sim time
// (bus/testing.hpp).
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&tr::register_nodes, &tinyline::laser_clustering::register_nodes}) {}
};

}  // namespace

TEST(TomatoNodes, AllAreRegistered) {
  bus::NodeRegistry r;
  tr::register_nodes(r);
  for (const char* t : {"tomato_detector", "pick_verifier", "truss_camera", "hand_laser"})
    EXPECT_NE(r.find("tomato_reasoning", t), nullptr) << t;
}

TEST(TomatoNodes, CloudConversionRoundTripsAndRejectsShortData) {
  tr::ColorCloud c;
  c.width = 2;
  c.height = 2;
  c.xyz = {{0, 0, 1}, {NAN, NAN, NAN}, {0.1f, 0.2f, 0.3f}, {1, 2, 3}};
  c.rgb = {{200, 10, 20}, {0, 0, 0}, {1, 2, 3}, {255, 255, 255}};
  PointCloud2 m;
  tr::nodes::to_msg(c, m);
  EXPECT_FALSE(m.is_dense);
  tr::ColorCloud back;
  ASSERT_EQ(tr::nodes::to_core(m, back), "");
  EXPECT_EQ(back.width, 2);
  EXPECT_EQ(back.height, 2);
  EXPECT_EQ(back.rgb, c.rgb);
  EXPECT_EQ(back.xyz[2], c.xyz[2]);
  EXPECT_FALSE(back.finite(1));
  m.data.resize(m.data.size() - 1);
  EXPECT_THAT(tr::nodes::to_core(m, back), ::testing::HasSubstr("too few"));
  m.fields.pop_back();
  EXPECT_THAT(tr::nodes::to_core(m, back), ::testing::HasSubstr("rgb"));
}

TEST(TomatoNodes, DetectorSaysWhyABadCloudHasNoTomatoes) {
  Harness h;
  bus::NodeOptions o;
  o.name = "detector";
  h.add("tomato_reasoning", "tomato_detector", o);
  std::vector<std::shared_ptr<const TomatoEstimates>> got;
  auto sub = h.io->create_subscription<TomatoEstimates>("tomatoes", bus::QoS::keep_last(10),
                                                        [&](const std::shared_ptr<const TomatoEstimates>& m) { got.push_back(m); });
  auto pub = h.io->create_publisher<PointCloud2>("cloud");
  h.ex.spin_until_idle();
  pub->publish(std::make_unique<PointCloud2>());  // no fields
  tr::ColorCloud green;
  for (int i = 0; i < 500; ++i) green.push_back({0.01f * float(i % 20), 0.01f * float(i / 20), 0.5f}, {20, 200, 30});
  auto m = std::make_unique<PointCloud2>();
  tr::nodes::to_msg(green, *m);
  pub->publish(std::move(m));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0]->stage, "input");
  EXPECT_TRUE(got[0]->tomatoes.empty());
  EXPECT_EQ(got[1]->stage, "hsi");
  EXPECT_EQ(got[1]->red_points, 0u);
}

TEST(TomatoNodes, HarvestPipelineFindsOrdersAndVerifiesEveryTomato) {
  Harness h;
  bus::NodeOptions cam, det, ver, laser, finder;
  cam.name = "camera";
  cam.param("truss_class", std::string("A")).param("seed", std::int64_t(3)).param("rate_hz", 1.0);
  cam.remap("cloud", "/camera/cloud").remap("truth", "/camera/truth");
  det.name = "detector";
  det.remap("cloud", "/camera/cloud").remap("tomatoes", "/tomatoes").remap("markers", "/tomatoes/markers");
  ver.name = "verifier";
  ver.remap("tomatoes", "/tomatoes").remap("pick_pose", "/hand/pick_pose").remap("expected_pedicel", "/hand/expected_pedicel");
  ver.remap("pedicel", "/hand/pedicel").remap("verification", "/verification").remap("markers", "/verification/markers");
  laser.name = "hand_laser";
  laser.param("truss_class", std::string("A")).param("seed", std::int64_t(3));
  laser.remap("pick_pose", "/hand/pick_pose").remap("scan", "/hand/scan").remap("verification", "/verification");
  finder.name = "pedicel_finder";
  finder.param("scissor_centre_z_m", 0.12);
  finder.remap("scan", "/hand/scan").remap("expected_pedicel", "/hand/expected_pedicel").remap("pedicel", "/hand/pedicel");
  h.add("tomato_reasoning", "truss_camera", cam);
  h.add("tomato_reasoning", "tomato_detector", det);
  h.add("tomato_reasoning", "pick_verifier", ver);
  h.add("tomato_reasoning", "hand_laser", laser);
  h.add("laser_clustering", "pedicel_finder", finder);
  std::vector<std::shared_ptr<const TomatoEstimates>> tomatoes;
  std::vector<std::shared_ptr<const PickVerification>> verified;
  std::vector<std::shared_ptr<const MarkerArray>> markers;
  auto s1 = h.io->create_subscription<TomatoEstimates>("/tomatoes", bus::QoS::keep_last(10),
                                                       [&](const std::shared_ptr<const TomatoEstimates>& m) { tomatoes.push_back(m); });
  auto s2 = h.io->create_subscription<PickVerification>("/verification", bus::QoS::keep_last(10),
                                                        [&](const std::shared_ptr<const PickVerification>& m) { verified.push_back(m); });
  auto s3 = h.io->create_subscription<MarkerArray>("/tomatoes/markers", bus::QoS::keep_last(10),
                                                   [&](const std::shared_ptr<const MarkerArray>& m) { markers.push_back(m); });
  h.ex.advance_to(bus::Time::from_seconds(100.0));  // starts the nodes; timers count from here
  EXPECT_TRUE(tomatoes.empty());  // the camera's first frame comes one period after start
  h.ex.advance_to(bus::Time::from_seconds(101.0));
  h.ex.spin_until_idle();
  ASSERT_EQ(tomatoes.size(), 1u);
  const auto& t = *tomatoes.front();
  ASSERT_FALSE(t.tomatoes.empty()) << t.stage << ": " << t.reason;
  EXPECT_EQ(t.header.frame_id, "camera");
  EXPECT_EQ(t.pick_order.size(), t.tomatoes.size());
  ASSERT_EQ(verified.size(), t.tomatoes.size());
  for (std::size_t k = 0; k < verified.size(); ++k) {
    EXPECT_EQ(verified[k]->pick_rank, int(k));
    EXPECT_EQ(verified[k]->tomato, t.pick_order[k]);
    // Class A trusses are simple: the laser finds the pedicel near the plan.
    EXPECT_TRUE(verified[k]->outcome == PickVerification::CUT_HERE || verified[k]->outcome == PickVerification::MOVE)
        << verified[k]->reason;
    const auto& c = verified[k]->cut_point;
    const auto& p = verified[k]->planned_cut;
    EXPECT_LT(std::hypot(c.x - p.x, c.y - p.y, c.z - p.z), 0.03);
  }
  ASSERT_FALSE(markers.empty());
  EXPECT_GE(markers.front()->markers.size(), 1 + 4 * t.tomatoes.size());
  EXPECT_TRUE(h.log->contains(bus::LogLevel::Info, "harvest summary"));
}
