// SPDX-License-Identifier: Apache-2.0
// The line_clusterer node (two-stage clustering of each scan).

#include "node_rig.hpp"

TEST(LaserClusteringNodes, LineClustererPublishesObjectsAndNotesBadScans) {
  Harness h;
  bus::NodeOptions o;
  o.name = "clusterer";
  o.remap("scan", "/laser/scan").remap("clusters", "/laser/clusters").param("objects_eps_m", 0.008);
  h.add("line_clusterer", o);
  auto& got = h.collect<LineClusters>("/laser/clusters", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("/laser/scan");
  const auto s = pedicel_scene(0.02);
  pub->publish(to_msg(s.scan, 1.0));
  auto broken = to_msg(s.scan, 1.1);
  broken->status.pop_back();
  pub->publish(std::move(broken));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  const auto& c = *got[0];
  EXPECT_EQ(c.header.frame_id, "laser");
  EXPECT_EQ(c.labels.size(), 256u);
  EXPECT_EQ(c.fate.size(), 256u);
  // The pedicel is one narrow object at x 2 cm.
  int narrow = 0;
  for (const auto& k : c.clusters) {
    if (std::abs(k.width_m - 0.006) < 0.0015 && std::abs(k.centroid_x_m - 0.02) < 0.002) ++narrow;
  }
  EXPECT_EQ(narrow, 1);
  EXPECT_TRUE(got[1]->clusters.empty());
  EXPECT_THAT(got[1]->note, HasSubstr("255 statuses"));
}

TEST(LaserClusteringNodes, MinReflectanceDropsDimReturns) {
  Harness h;
  bus::NodeOptions o;
  o.name = "clusterer";
  o.param("min_reflectance", 10.0);
  h.add("line_clusterer", o);
  auto& got = h.collect<LineClusters>("clusters", bus::QoS::keep_last(10));
  auto pub = h.io->create_publisher<LineScan>("scan");
  auto bright = to_msg(pedicel_scene(0.02).scan, 1.0);
  bright->reflectance.assign(bright->distance_m.size(), 20.0f);
  auto dim = to_msg(pedicel_scene(0.02).scan, 1.1);
  dim->reflectance.assign(dim->distance_m.size(), 5.0f);
  pub->publish(std::move(bright));
  pub->publish(std::move(dim));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_FALSE(got[0]->clusters.empty());
  EXPECT_TRUE(got[1]->clusters.empty()) << "every pixel is below min_reflectance";
  for (const int l : got[1]->labels) EXPECT_LT(l, 0);
}
