// SPDX-License-Identifier: Apache-2.0
// hydrus_sim on the bus: stepped on sim time, it publishes the manoeuvre's
// joint angles and the true cylinder in the robot frame, and moves the
// sensors of the process's shared simulated system.
#include <cmath>

#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include <sim/system.hpp>

#include <hydrus_fitting/trajectory.hpp>
#include <hydrus_fitting/sim/hydrus_sim_node.hpp>
#include <hydrus_fitting/sim/register.hpp>

namespace hf = tinyline::hydrus_fitting;
namespace bus = tinyline::bus;
using tinyline::sensor_msgs::msg::JointState;
using tinyline::tinyline_msgs::msg::CircleFit;

namespace {

const std::string kSrc = TINYLINE_SOURCE_DIR;

// The hydrus_sim node on stepped sim time (bus/testing.hpp), with its joint
// states and ground truth kept.
struct Rig : bus::testing::NodeRig {
  Rig() : NodeRig({&hf::register_sim_nodes}) {}
  std::vector<std::shared_ptr<const JointState>>& joints = collect<JointState>("joint_states");
  std::vector<std::shared_ptr<const CircleFit>>& truth = collect<CircleFit>("truth");
  std::shared_ptr<bus::Node> add(bus::NodeOptions o) {
    return NodeRig::add("hydrus_fitting", "hydrus_sim", std::move(o));
  }
};

}  // namespace

TEST(HydrusSimNode, PublishesTheManoeuvreAndMovesTheSensors) {
  Rig r;
  const std::string scene = kSrc + "/sim/config/scenes/hydrus4_grasp.yaml";
  auto system = tinyline::sim::SimulatedSystem::shared(scene);  // the node shares it
  const Eigen::Vector3d laser4_before = system->sensor_pose(system->sensor_index("laser4")).translation();
  bus::NodeOptions o;
  o.name = "robot";
  o.param("scene", scene).param("robot_description", kSrc + "/hydrus_fitting/config/hydrus4.yaml").param("loop", false);
  auto node = std::dynamic_pointer_cast<hf::sim_nodes::HydrusSimNode>(r.add(o));
  ASSERT_NE(node, nullptr);
  r.ex.advance_to(bus::Time::from_seconds(0.0));  // starts the node (its timer)
  r.ex.advance_to(bus::Time::from_seconds(8.0));  // mid-way through closing the links
  ASSERT_GT(r.joints.size(), 700u);               // 100 Hz
  ASSERT_EQ(r.joints.size(), r.truth.size());
  const hf::ApproachParams a;
  const auto& q = *r.joints.back();
  ASSERT_EQ(q.name.size(), 3u);
  EXPECT_EQ(q.name[0], "joint1");
  const double t = node->manoeuvre_time_s();
  EXPECT_NEAR(t, 8.0, 0.02);
  EXPECT_NEAR(q.position[0], hf::approach_pose(a, t).joints_rad[0], 1e-9);
  // The truth in the robot frame: the cylinder's axis is the world origin.
  const auto& c = *r.truth.back();
  const Eigen::Vector2d expect = hf::approach_pose(a, t).T_world_base().inverse() * Eigen::Vector2d::Zero();
  EXPECT_NEAR(c.centre.x, expect.x(), 1e-9);
  EXPECT_NEAR(c.centre.y, expect.y(), 1e-9);
  EXPECT_DOUBLE_EQ(c.radius_m, 0.10);
  // The last link's sensor has swung in with the joints.
  const Eigen::Vector3d laser4_now = system->sensor_pose(system->sensor_index("laser4")).translation();
  EXPECT_GT((laser4_now - laser4_before).norm(), 0.3);
}

TEST(HydrusSimNode, AMissingSceneStopsTheStart) {
  Rig r;
  bus::NodeOptions o;
  o.name = "robot";
  o.param("scene", kSrc + "/sim/config/scenes/no_such_scene.yaml")
      .param("robot_description", kSrc + "/hydrus_fitting/config/hydrus4.yaml");
  EXPECT_ANY_THROW({
    r.add(o);
    r.ex.advance_to(bus::Time::from_seconds(0.1));
  });
}
