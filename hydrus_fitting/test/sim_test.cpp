// SPDX-License-Identifier: Apache-2.0
// The Hydrus in the physics simulator: the scene agrees with the robot
// description, bad scenes are named, and crosstalk is there without the
// sequencer and gone with it (short windows of eval/sim_study).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <sim/config_error.hpp>
#include <sim/scene.hpp>
#include <sim/scenes/hydrus.hpp>
#include <sim/system.hpp>

#include "hydrus_fitting/robot_model.hpp"
#include <hydrus_fitting/sim/simulated_hydrus.hpp>
#include "hydrus_fitting/trajectory.hpp"
#include "sim_study.hpp"

using namespace tinyline;
using namespace tinyline::hydrus_fitting;

namespace {

const std::string kSrc = TINYLINE_SOURCE_DIR;
const std::string kScene = kSrc + "/sim/config/scenes/hydrus4_grasp.yaml";
const std::string kRobot = kSrc + "/hydrus_fitting/config/hydrus4.yaml";

eval::SimStudyParams study(const std::string& schedule, double start_s, double end_s) {
  eval::SimStudyParams p;
  p.scene_path = kScene;
  p.robot_description = kRobot;
  p.calibration_path = kSrc + "/tiny_laser_driver/config/calibration/sim_tiny_tof_3p6mm.yaml";
  p.schedule = schedule;
  p.start_s = start_s;
  p.end_s = end_s;
  return p;
}

double corrupted_share(const eval::SimStudyResult& r) {
  long valid = 0, bad = 0;
  for (const auto& u : r.updates) {
    valid += u.valid_pixels;
    bad += u.corrupted_pixels;
  }
  return valid > 0 ? static_cast<double>(bad) / static_cast<double>(valid) : 1.0;
}

}  // namespace

TEST(HydrusScene, TheSceneIsTheRobotDescriptionAtTheStartOfTheApproach) {
  const sim::Scene scene = sim::load_scene(kScene);
  const RobotModel model = RobotModel::load(kRobot);
  const RobotPose2D start = approach_pose(ApproachParams{}, 0.0);
  const Kinematics k = model.forward(start.joints_rad);
  const double height = scene.truth.at("sensing_height_m").at(0);
  for (std::size_t s = 0; s < model.sensors().size(); ++s) {
    const sim::SensorMount* m = scene.sensor(model.sensors()[s].name);
    ASSERT_NE(m, nullptr) << model.sensors()[s].name;
    const Eigen::Isometry2d T = start.T_world_base() * k.T_base_sensor[s];
    const Eigen::Isometry3d expected = sim::planar_sensor_frame(T.translation(), Eigen::Rotation2Dd(T.linear()).angle(),
                                                                height, model.sensors()[s].line_axis_left);
    EXPECT_LT((m->T_world_sensor.matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-9) << m->name;
    // The receiver's focal length is the description's (fields of view agree).
    EXPECT_DOUBLE_EQ(m->params.lens.focal_mm, model.sensors()[s].focal_mm);
  }
  for (const auto& l : model.links()) EXPECT_TRUE(scene.world.find(l.name).has_value()) << l.name;
}

TEST(HydrusScene, PlanarSensorFrameLooksAlongYawWithTheLineToTheLeft) {
  const Eigen::Isometry3d T = sim::planar_sensor_frame({1.0, 2.0}, M_PI / 2, 0.5, true);
  EXPECT_LT((T.linear().col(2) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-12);   // optical axis +y
  EXPECT_LT((T.linear().col(0) - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-12);  // line to the left of +y
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
  const Eigen::Isometry3d R = sim::planar_sensor_frame({0, 0}, 0.0, 0.0, false);
  EXPECT_LT((R.linear().col(0) - Eigen::Vector3d(0, -1, 0)).norm(), 1e-12);
  EXPECT_NEAR(R.linear().determinant(), 1.0, 1e-12);
}

TEST(HydrusScene, GeneratorErrorsNameTheFieldAndLine) {
  const std::string bad_joints = "name: x\ngenerators:\n  - type: hydrus\n    links: 4\n    joints_deg: [10, 20]\n";
  try {
    (void)sim::load_scene_string(bad_joints, "bad.yaml", kSrc + "/sim/config/scenes");
    FAIL() << "expected a ConfigError";
  } catch (const sim::ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find("joints_deg"), std::string::npos) << what;
    EXPECT_NE(what.find("needs 3 angles"), std::string::npos) << what;
  }
  const std::string bad_key = "name: x\ngenerators:\n  - {type: hydrus, linkz: 4}\n";
  EXPECT_THROW((void)sim::load_scene_string(bad_key, "bad.yaml", "."), sim::ConfigError);
  const std::string bad_material = "name: x\ngenerators:\n  - {type: hydrus, material: unobtainium}\n";
  EXPECT_THROW((void)sim::load_scene_string(bad_material, "bad.yaml", "."), sim::ConfigError);
}

TEST(HydrusScene, ASensorOfTheDescriptionMissingFromTheSceneIsNamed) {
  const std::string text = R"(
name: one_sensor
generators:
  - {type: hydrus, links: 4, sensor_config: SENSORS/tiny_tof_3p6mm.yaml}
truth: {cylinder_centre_m: [0, 0], cylinder_radius_m: 0.1, sensing_height_m: 0.5}
)";
  std::string scene = text;
  scene.replace(scene.find("SENSORS"), 7, kSrc + "/sim/config/sensors");
  sim::SimulatedSystem sys(sim::load_scene_string(scene, "one.yaml", kSrc + "/sim/config/scenes"));
  RobotModel model = RobotModel::load(kRobot);
  EXPECT_NO_THROW(SimulatedHydrus(sys, model));
  std::string yaml = R"(
name: five
links:
  - {name: link1, length_m: 0.5, width_m: 0.08}
  - {name: link2, length_m: 0.5, width_m: 0.08, joint: {name: joint1}}
sensors:
  - {name: laser9, link: link1, position_m: [0.25, 0.05], yaw_deg: 90, focal_mm: 3.6}
)";
  const RobotModel other = RobotModel::parse(yaml, "five.yaml");
  try {
    SimulatedHydrus h(sys, other);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("laser9"), std::string::npos) << e.what();
  }
}

// With every laser on and the pulse trains in phase (started together), each
// sensor's gates catch the others' light off the cylinder: a large share of
// its pixels are centimetres off and the first fit is decimetres off. The
// sequenced schedules keep every other laser off while a sensor measures.
// (The clocks differ by tens of ppm, so the trains drift out of phase within
// a few tenths of a second and crosstalk comes back whenever they realign:
// docs/hydrus_fitting.md.)
TEST(HydrusSim, CrosstalkWithoutSequencingIsGoneWithTheColouringSchedule) {
  const double t0 = ApproachParams{}.approach_s + ApproachParams{}.close_s;  // closed around the cylinder
  const auto all_on = eval::sim_study(study("all_on", t0, t0 + 0.12));
  const auto colour = eval::sim_study(study("colouring", t0, t0 + 0.25));
  ASSERT_GE(all_on.updates.size(), 3u);
  ASSERT_GE(colour.updates.size(), 5u);
  const auto& first_on = all_on.updates.front();
  EXPECT_EQ(first_on.sets, 4);
  EXPECT_GT(first_on.crosstalk_pulses, 1000);
  EXPECT_GT(first_on.corrupted_pixels, 0.4 * first_on.valid_pixels);
  EXPECT_TRUE(first_on.status != 0 || first_on.centre_error_m > 0.05) << first_on.centre_error_m;

  for (const auto& u : colour.updates) {
    EXPECT_EQ(u.crosstalk_pulses, 0) << u.t_s;
    EXPECT_LT(u.corrupted_pixels, 0.2 * u.valid_pixels) << u.t_s;
  }
  EXPECT_LT(corrupted_share(colour), 0.5 * static_cast<double>(first_on.corrupted_pixels) / first_on.valid_pixels);
  // Once every sensor has reported, the fit is within millimetres.
  const auto& last = colour.updates.back();
  ASSERT_EQ(last.status, 0);
  EXPECT_LT(last.centre_error_m, 0.01);
  EXPECT_LT(std::abs(last.radius_error_m), 0.01);
}

// Rates per sensor in the same world: all on runs at the set rate; the
// sequenced schedules at 1 / (slots x slot). Around the cylinder with 76 deg
// fans every pair of sensors conflicts, so the colouring needs as many slots
// as the thesis's time slicing; it is not slower (but for the turn a sensor
// loses when a changed schedule restarts at its first slot).
TEST(HydrusSim, RatesFollowTheScheduleAndColouringIsNeverSlower) {
  const double t0 = ApproachParams{}.approach_s + ApproachParams{}.close_s;
  const auto on = eval::sim_study(study("all_on", t0, t0 + 0.5));
  const auto slicing = eval::sim_study(study("time_slicing", t0, t0 + 0.5));
  const auto colour = eval::sim_study(study("colouring", t0, t0 + 0.5));
  ASSERT_EQ(slicing.sensors.size(), 4u);
  ASSERT_EQ(colour.sensors.size(), 4u);
  const double set_s = on.set_period_s;
  for (std::size_t s = 0; s < 4; ++s) {
    EXPECT_NEAR(on.sensors[s].rate_hz, 1.0 / set_s, 0.1 / set_s);
    EXPECT_NEAR(slicing.sensors[s].rate_hz, 1.0 / (4 * (set_s + 0.002)), 0.3 / (4 * (set_s + 0.002)));
    // A changed schedule restarts at its first slot: a sensor may lose one turn per change.
    EXPECT_GE(colour.sensors[s].sets + 1, slicing.sensors[s].sets) << colour.sensors[s].sensor;
  }
  EXPECT_EQ(colour.updates.back().colours, 4);
}

TEST(HydrusSim, AnUnknownScheduleIsRefused) {
  EXPECT_THROW((void)eval::sim_study(study("round_robin", 0.0, 0.1)), std::invalid_argument);
}
