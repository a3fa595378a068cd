// SPDX-License-Identifier: Apache-2.0
// The reflectance_clusterer node.

#include "node_rig.hpp"

TEST(LaserClusteringNodes, ReflectanceClustererFindsTheMetal) {
  Harness h;
  bus::NodeOptions o;
  o.name = "refl";
  h.add("reflectance_clusterer", o);
  std::shared_ptr<const LineClusters> got;
  auto sub = h.io->create_subscription<LineClusters>("clusters", bus::QoS::keep_last(1),
                                                     [&](const std::shared_ptr<const LineClusters>& m) { got = m; });
  auto pub = h.io->create_publisher<LineScan>("scan");
  pub->publish(to_msg(stick_scan(0.0, 0.0, 3), 1.0));
  h.ex.spin_until_idle();
  ASSERT_TRUE(got);
  ASSERT_GE(got->brightest, 0);
  const auto& c = got->clusters[static_cast<std::size_t>(got->brightest)];
  EXPECT_NEAR(c.reflectance, 37.0, 4.0);
  EXPECT_NEAR(c.centroid_x_m, 0.0, 0.002);
}
