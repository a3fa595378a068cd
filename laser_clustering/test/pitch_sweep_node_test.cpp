// SPDX-License-Identifier: Apache-2.0
// The pitch_sweep node.

#include "node_rig.hpp"

TEST(LaserClusteringNodes, PitchSweepCommandsTheSweepThenTheFoundPitch) {
  Harness h;
  bus::NodeOptions o;
  o.name = "sweep";
  o.param("from_deg", -4.0).param("to_deg", 4.0).param("step_deg", 2.0).param("dwell_s", 0.1);
  h.add("pitch_sweep", o);
  std::vector<double> commands;
  std::vector<AlignmentResult> aligned;
  auto s1 = h.io->create_subscription<JointState>("joint_command", bus::QoS::keep_last(50),
                                                  [&](const JointState& m) { commands.push_back(m.position.at(0)); });
  auto s2 = h.io->create_subscription<AlignmentResult>("aligned", bus::QoS::keep_last(5),
                                                       [&](const AlignmentResult& m) { aligned.push_back(m); });
  auto pub = h.io->create_publisher<AlignmentResult>("alignment");
  h.ctx->clock().set_sim_time(bus::Time::from_seconds(10.0));
  h.ex.advance_to(bus::Time::from_seconds(10.45));
  ASSERT_EQ(commands.size(), 4u) << "one pitch per dwell";
  EXPECT_TRUE(aligned.empty());
  auto r = std::make_unique<AlignmentResult>();
  r->outcome = AlignmentResult::FOUND;
  r->best_pitch_rad = 0.01;
  pub->publish(std::move(r));
  h.ex.advance_to(bus::Time::from_seconds(11.0));
  ASSERT_EQ(commands.size(), 6u) << "5 pitches and the found one";
  EXPECT_NEAR(commands.front(), -4.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_NEAR(commands[4], 4.0 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(commands.back(), 0.01);
  ASSERT_EQ(aligned.size(), 1u);
  EXPECT_EQ(aligned[0].outcome, AlignmentResult::FOUND);
}

TEST(LaserClusteringNodes, PitchSweepWithoutAResultSaysWhyAndStays) {
  Harness h;
  bus::NodeOptions o;
  o.name = "sweep";
  o.param("from_deg", -2.0).param("to_deg", 2.0).param("step_deg", 2.0).param("dwell_s", 0.1);
  h.add("pitch_sweep", o);
  std::vector<double> commands;
  std::vector<AlignmentResult> aligned;
  auto s1 = h.io->create_subscription<JointState>("joint_command", bus::QoS::keep_last(50),
                                                  [&](const JointState& m) { commands.push_back(m.position.at(0)); });
  auto s2 = h.io->create_subscription<AlignmentResult>("aligned", bus::QoS::keep_last(5),
                                                       [&](const AlignmentResult& m) { aligned.push_back(m); });
  h.ctx->clock().set_sim_time(bus::Time::from_seconds(10.0));
  h.ex.advance_to(bus::Time::from_seconds(11.0));
  EXPECT_EQ(commands.size(), 3u) << "no move after the sweep";
  ASSERT_EQ(aligned.size(), 1u);
  EXPECT_EQ(aligned[0].outcome, AlignmentResult::INVALID_INPUT);
  EXPECT_THAT(aligned[0].reason, HasSubstr("no alignment result"));
}

TEST(LaserClusteringNodes, PitchSweepRejectsAnEmptyOrTooShortSweep) {
  Harness h;
  bus::NodeOptions backwards;
  backwards.name = "a";
  backwards.param("from_deg", 5.0).param("to_deg", -5.0);
  try {
    h.add("pitch_sweep", backwards);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("to_deg"));
  }
  bus::NodeOptions short_sweep;
  short_sweep.name = "b";
  short_sweep.param("from_deg", 0.0).param("to_deg", 1.0).param("step_deg", 0.6);
  try {
    h.add("pitch_sweep", short_sweep);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("at least 3"));
  }
}
