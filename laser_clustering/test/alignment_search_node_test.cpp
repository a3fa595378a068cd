// SPDX-License-Identifier: Apache-2.0
// The alignment_search node.

#include "node_rig.hpp"

TEST(LaserClusteringNodes, AlignmentSearchFindsThePitchOfAPitchSweep) {
  Harness h;
  bus::NodeOptions o;
  o.name = "align";
  o.param("pitch_joint", std::string("wrist_pitch"));
  o.param("surface_quantile", 0.99);  // the stick is about 3 % of the pixels
  h.add("alignment_search", o);
  auto& got = h.collect<AlignmentResult>("alignment", bus::QoS::keep_last(100));
  auto scans = h.io->create_publisher<LineScan>("scan");
  auto joints = h.io->create_publisher<JointState>("joint_states");
  const double deg = std::numbers::pi / 180.0, best = 3.3 * deg;
  // A scan without a pitch reading first: an explicit invalid result.
  scans->publish(to_msg(stick_scan(0.0, best, 1), 0.5));
  h.ex.spin_until_idle();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0]->outcome, AlignmentResult::INVALID_INPUT);
  EXPECT_THAT(got[0]->reason, HasSubstr("no 'wrist_pitch' reading"));
  // The sweep: -10 .. +10 degrees in 2 degree steps, one scan per step.
  int k = 0;
  for (double p = -10 * deg; p <= 10.01 * deg; p += 2 * deg, ++k) {
    const double t = 1.0 + 0.1 * k;
    auto j = std::make_unique<JointState>();
    j->header.stamp = bus::Time::from_seconds(t).to_msg();
    j->name = {"elbow", "wrist_pitch"};
    j->position = {0.3, p};
    joints->publish(std::move(j));
    scans->publish(to_msg(stick_scan(p, best, static_cast<unsigned>(k + 10)), t + 0.01));
    h.ex.spin_until_idle();
  }
  const auto& last = *got.back();
  EXPECT_EQ(last.outcome, AlignmentResult::FOUND) << last.reason;
  EXPECT_EQ(last.num_samples, 11u);
  EXPECT_TRUE(last.refined);
  EXPECT_NEAR(last.best_pitch_rad, best, 0.5 * deg);
}
