// SPDX-License-Identifier: Apache-2.0
// The pipeline on PCL clouds gives what it gives on ColorClouds: the same
// frames of the simulator's RGB-D camera, organised and not, one and two views.
#include <gtest/gtest.h>

#include <cmath>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pcl_conversions.hpp"
#include "tomato_reasoning/pipeline.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

void expect_same_detections(const PipelineResult& a, const PipelineResult& b) {
  ASSERT_EQ(a.status.ok(), b.status.ok()) << a.status.message << " / " << b.status.message;
  EXPECT_EQ(a.finite_points, b.finite_points);
  EXPECT_EQ(a.red_points, b.red_points);
  ASSERT_EQ(a.tomatoes.size(), b.tomatoes.size());
  for (std::size_t i = 0; i < a.tomatoes.size(); ++i) {
    EXPECT_EQ(a.tomatoes[i].fit.sphere.centre, b.tomatoes[i].fit.sphere.centre) << "tomato " << i;
    EXPECT_EQ(a.tomatoes[i].fit.sphere.radius_m, b.tomatoes[i].fit.sphere.radius_m) << "tomato " << i;
    EXPECT_EQ(a.tomatoes[i].pedicel.expected_dir, b.tomatoes[i].pedicel.expected_dir) << "tomato " << i;
  }
  EXPECT_EQ(a.pick_order, b.pick_order);
}

pcl::PointCloud<pcl::PointXYZRGB> without_nan(const pcl::PointCloud<pcl::PointXYZRGB>& in) {
  pcl::PointCloud<pcl::PointXYZRGB> out;
  for (const auto& p : in.points)
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) out.points.push_back(p);
  out.width = static_cast<std::uint32_t>(out.points.size());
  out.height = 1;
  out.is_dense = true;
  return out;
}

}  // namespace

TEST(PclClouds, OrganisedAndUnorganisedPclCloudsGiveTheColorCloudsDetections) {
  for (const auto& [cls, seed] :
       {std::pair{sim::TrussClass::kA, 3u}, std::pair{sim::TrussClass::kB, 1u}, std::pair{sim::TrussClass::kC, 2u}}) {
    const eval::Scenario s = eval::make_scenario(cls, seed);
    PipelineParams p;
    p.gravity = s.gravity_camera;
    const TomatoPipeline pipe(p);
    const PipelineResult reference = pipe.run(s.cloud());
    ASSERT_TRUE(reference.status.ok()) << reference.status.message;
    ASSERT_GT(reference.tomatoes.size(), 0u);

    const pcl::PointCloud<pcl::PointXYZRGB> organised = to_pcl(s.cloud());
    ASSERT_TRUE(organised.isOrganized());
    expect_same_detections(reference, pipe.run(view_of(organised)));

    const pcl::PointCloud<pcl::PointXYZRGB> dense = without_nan(organised);
    ASSERT_FALSE(dense.isOrganized());
    const PipelineResult unorganised = pipe.run(view_of(dense));
    expect_same_detections(reference, unorganised);
  }
}

TEST(PclClouds, TwoViewsOfPclCloudsGiveTheColorCloudsDetections) {
  eval::ScenarioOptions two;
  two.views = 2;
  const eval::Scenario s = eval::make_scenario(sim::TrussClass::kC, 1002, two);
  PipelineParams p;
  p.gravity = s.gravity_camera;
  const TomatoPipeline pipe(p);
  const pcl::PointCloud<pcl::PointXYZRGB> c0 = to_pcl(s.clouds[0]), c1 = to_pcl(s.clouds[1]);
  const PipelineResult reference =
      pipe.run({View{s.clouds[0], s.T_ref_camera[0]}, View{s.clouds[1], s.T_ref_camera[1]}});
  ASSERT_TRUE(reference.status.ok()) << reference.status.message;
  expect_same_detections(reference,
                         pipe.run({View{view_of(c0), s.T_ref_camera[0]}, View{view_of(c1), s.T_ref_camera[1]}}));
}

TEST(PclClouds, TheViewReadsThePclPointsInPlace) {
  pcl::PointCloud<pcl::PointXYZRGBA> cloud(2, 2);
  for (std::size_t k = 0; k < 4; ++k) {
    auto& p = cloud.points[k];
    p.x = static_cast<float>(k);
    p.y = 2.0f * static_cast<float>(k);
    p.z = -1.0f;
    p.r = static_cast<std::uint8_t>(10 + k);
    p.g = 20;
    p.b = static_cast<std::uint8_t>(30 + k);
    p.a = 255;
  }
  cloud.points[3].z = NAN;
  const CloudView v = view_of(cloud);
  EXPECT_TRUE(check_view(v).ok());
  EXPECT_EQ(v.width, 2);
  EXPECT_EQ(v.height, 2);
  EXPECT_TRUE(v.organised());
  EXPECT_EQ(reinterpret_cast<const float*>(v.xyz), &cloud.points[0].x);  // no copy
  EXPECT_EQ(v.point(2), Eigen::Vector3f(2, 4, -1));
  EXPECT_EQ(v.colour(2), (Rgb{12, 20, 32}));
  EXPECT_TRUE(v.finite(2));
  EXPECT_FALSE(v.finite(3));
  cloud.points[1].r = 99;  // a view, not a snapshot
  EXPECT_EQ(v.colour(1)[0], 99);

  const ColorCloud owned = to_color_cloud(cloud);
  EXPECT_TRUE(check_cloud(owned).ok());
  EXPECT_EQ(owned.width, 2);
  EXPECT_EQ(owned.rgb[1], (Rgb{99, 20, 31}));
  const pcl::PointCloud<pcl::PointXYZRGB> back = to_pcl(owned);
  EXPECT_FALSE(back.is_dense);
  EXPECT_EQ(back.points[2].b, 32);
}

TEST(PclClouds, AMalformedOrEmptyPclCloudStopsAtTheInput) {
  const TomatoPipeline pipe;
  pcl::PointCloud<pcl::PointXYZRGB> broken(4, 3);
  broken.points.pop_back();  // 4 x 3 but 11 points
  const PipelineResult r = pipe.run(view_of(broken));
  EXPECT_EQ(r.stage, PipelineStage::kInput);
  EXPECT_NE(r.status.message.find("4 x 3 but holds 11 points"), std::string::npos) << r.status.message;

  const pcl::PointCloud<pcl::PointXYZRGB> empty;
  EXPECT_EQ(pipe.run(view_of(empty)).status.message, "empty cloud");
}
