// SPDX-License-Identifier: Apache-2.0
#include "sim_study.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include <sim/firmware.hpp>
#include <sim/system.hpp>
#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

#include "hydrus_fitting/estimator.hpp"
#include "hydrus_fitting/robot_model.hpp"
#include "hydrus_fitting/sequencer.hpp"
#include <hydrus_fitting/sim/simulated_hydrus.hpp>

namespace tinyline::hydrus_fitting::eval {

namespace {

namespace drv = tinyline::tiny_laser_driver;

struct SensorRun {
  std::size_t sim_index = 0;
  std::string name;
  std::vector<double> angle, range;
  std::int64_t stamp_ns = 0;
  bool have = false;
  int sets = 0;
  long valid = 0, corrupted = 0;
  std::uint64_t index = 0;
};

std::int64_t to_ns(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

}  // namespace

SimStudyResult sim_study(const SimStudyParams& p) {
  if (p.schedule != "all_on" && p.schedule != "time_slicing" && p.schedule != "colouring")
    throw std::invalid_argument("sim_study: schedule must be all_on, time_slicing or colouring, got '" + p.schedule +
                                "'");
  if (const common::Validation why = p.approach.validate(); !why.valid)
    throw std::invalid_argument("sim_study: " + why.reason);

  const RobotModel model = RobotModel::load(p.robot_description);
  sim::SimulatedSystem sys(sim::load_scene(p.scene_path));
  SimulatedHydrus robot(sys, model);  // throws naming what the scene lacks
  const double truth_radius = robot.cylinder_radius_m();
  const auto cylinder_id = sys.with_scene([](const sim::Scene& s) { return s.world.find("cylinder"); });
  if (!cylinder_id) throw std::runtime_error("sim_study: scene " + p.scene_path + " has no object 'cylinder'");
  const sim::ObjectId cylinder = *cylinder_id;

  std::vector<SensorRun> sensors(model.sensors().size());
  for (std::size_t s = 0; s < sensors.size(); ++s) {
    sensors[s].name = model.sensors()[s].name;
    sensors[s].sim_index = robot.sim_sensor(s);
  }

  const auto& sp = sys.sensor(sensors.front().sim_index).params();
  const std::vector<int> pulses = sp.acquisition.raw_pulses;
  const double set_s = pulses.back() / sp.emitter.pulse_rate_hz;
  drv::OpticsParams optics;
  optics.focal_mm = sp.lens.focal_mm;
  optics.sensor_length_mm = sp.lens.sensor_length_mm;
  const drv::ScanProcessor processor(drv::CalibrationModel::load(p.calibration_path), optics);

  auto place = [&](double t) {
    const RobotPose2D pose = approach_pose(p.approach, t);
    robot.place(pose);
    return pose;
  };

  JointStateBuffer joints(model.joint_names(), JointBufferParams{0.05, 5.0});
  BasePoseBuffer base_poses(BasePoseBufferParams{0.05, 5.0});
  CircleEstimator estimator(model);
  SequencerParams seq_params;
  seq_params.timing.set_period_s = set_s;
  seq_params.timing.guard_s = p.guard_s;
  Sequencer sequencer(model, seq_params);
  std::optional<Circle> object;

  SimStudyResult out;
  out.schedule = p.schedule;
  out.set_period_s = set_s;
  const double end = p.end_s < 0.0 ? p.approach.duration_s() : std::min(p.end_s, p.approach.duration_s());
  const double slot_s = p.schedule == "all_on" ? set_s : set_s + p.guard_s;
  const int n = static_cast<int>(sensors.size());
  // The joint stream: a JointState every 10 ms, as a flight controller sends.
  double next_joint_t = p.start_s;
  auto feed_joints_until = [&](double t) {
    for (; next_joint_t <= t + 1e-9; next_joint_t += 0.01) {
      const RobotPose2D q = approach_pose(p.approach, next_joint_t);
      joints.add(to_ns(next_joint_t), model.joint_names(), q.joints_rad);
      const Eigen::Isometry2d T = q.T_world_base();
      base_poses.add(to_ns(next_joint_t), T.translation(), std::atan2(T.linear()(1, 0), T.linear()(0, 0)));
    }
  };
  if (p.schedule == "all_on")
    for (const auto& s : sensors) sys.set_emitting(s.sim_index, true, p.start_s);

  int slot = 0;
  for (double t = p.start_s; t + set_s <= end + 1e-9; t += slot_s) {
    // The robot stands where it is in the middle of the set: the time the
    // scan is stamped with, and the mean of its pose over the accumulation.
    const RobotPose2D pose = place(t + 0.5 * set_s);
    feed_joints_until(t + set_s);
    // Who emits in this slot.
    std::vector<int> active;
    int colours = 1;
    if (p.schedule == "all_on") {
      for (int s = 0; s < n; ++s) active.push_back(s);
    } else if (p.schedule == "time_slicing") {
      active.push_back(slot % n);
      colours = n;
    } else {
      if (sequencer.update(pose.joints_rad, object)) slot = 0;  // a new schedule starts at its first slot
      const Schedule& sch = sequencer.schedule();
      colours = sch.slot_count();
      active = sch.slots[static_cast<std::size_t>(slot % sch.slot_count())];
    }
    if (p.schedule != "all_on") {
      for (int s = 0; s < n; ++s) {
        const bool on = std::find(active.begin(), active.end(), s) != active.end();
        sys.set_emitting(sensors[static_cast<std::size_t>(s)].sim_index, on, t);
        if (on) sys.set_emitting(sensors[static_cast<std::size_t>(s)].sim_index, false, t + set_s);
      }
    }
    SimUpdate u;
    u.t_s = t + set_s;
    u.colours = colours;
    for (const int s : active) {
      SensorRun& r = sensors[static_cast<std::size_t>(s)];
      // The scene's sensors are one calibrated unit (same per-pixel
      // constants): the set index alone seeds the noise, so each sensor gets
      // its own index range to keep their noise independent.
      const std::uint64_t index = p.seed * 1000003ULL + (r.sim_index + 1) * 100000007ULL + r.index++;
      const sim::SensorSet set = sys.measure(r.sim_index, t, pulses, index);
      drv::RawSet raw;
      raw.frames = sim::raw_frames(set);
      const drv::ProcessedScan scan = processor.process(raw, sys.sensor_time(t));
      r.angle.assign(processor.angles_rad().begin(), processor.angles_rad().end());
      r.range.resize(drv::kPixels);
      for (std::size_t i = 0; i < drv::kPixels; ++i) {
        const bool ok = scan.status[i] == drv::PixelStatus::kValid;
        r.range[i] = ok ? static_cast<double>(scan.distance_m[i]) : std::numeric_limits<double>::quiet_NaN();
        // Corruption is judged on the cylinder's clean pixels (not mixed with the background).
        if (!ok || i >= set.truth.size() || set.truth[i].object != cylinder || set.truth[i].mixed) continue;
        ++u.valid_pixels;
        ++r.valid;
        if (std::abs(r.range[i] - set.truth[i].range_m) > p.corrupt_threshold_m) {
          ++u.corrupted_pixels;
          ++r.corrupted;
        }
      }
      r.stamp_ns = to_ns(t + 0.5 * set_s);  // the middle of the accumulation
      r.have = true;
      ++r.sets;
      ++u.sets;
      u.crosstalk_pulses += set.crosstalk_pulses;
    }
    ++slot;

    std::vector<ScanView> views;
    for (const auto& r : sensors)
      if (r.have) views.push_back({r.name, r.stamp_ns, r.angle, r.range});
    const CircleEstimate e = estimator.estimate(views, joints, p.base_motion ? &base_poses : nullptr);
    // The truth in the robot frame at the newest scan's time.
    const RobotPose2D pose_now = approach_pose(p.approach, static_cast<double>(e.stamp_ns) * 1e-9);
    const Eigen::Vector2d truth = robot.centre_in_base(pose_now);
    u.status = static_cast<int>(e.fit.status);
    u.true_x_m = truth.x();
    u.true_y_m = truth.y();
    u.points = e.points;
    u.self_filtered = e.self_filtered;
    if (e.fit.ok()) {
      u.inliers = e.fit.points_used;
      u.centre_x_m = e.fit.circle.centre_m.x();
      u.centre_y_m = e.fit.circle.centre_m.y();
      u.radius_m = e.fit.circle.radius_m;
      u.centre_error_m = (e.fit.circle.centre_m - truth).norm();
      u.radius_error_m = e.fit.circle.radius_m - truth_radius;
      object = e.fit.circle;
    }
    out.updates.push_back(u);
  }
  out.simulated_s = end - p.start_s;
  for (const auto& r : sensors) {
    SimSensorRate rate;
    rate.sensor = r.name;
    rate.sets = r.sets;
    rate.rate_hz = out.simulated_s > 0.0 ? r.sets / out.simulated_s : 0.0;
    rate.corrupted_share = r.valid > 0 ? static_cast<double>(r.corrupted) / static_cast<double>(r.valid) : 0.0;
    out.sensors.push_back(rate);
  }
  return out;
}

std::string sim_updates_csv(const std::vector<SimStudyResult>& runs) {
  std::ostringstream o;
  o << "schedule,t_s,status,centre_error_m,radius_error_m,centre_x_m,centre_y_m,radius_m,true_x_m,true_y_m,points,"
       "inliers,self_filtered,sets,crosstalk_pulses,valid_pixels,corrupted_pixels,colours\n";
  for (const auto& r : runs)
    for (const auto& u : r.updates)
      o << fmt::format("{},{:.4f},{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{},{},{},{},{},{},{},{}\n",
                       r.schedule, u.t_s, u.status, u.centre_error_m, u.radius_error_m, u.centre_x_m, u.centre_y_m,
                       u.radius_m, u.true_x_m, u.true_y_m, u.points, u.inliers, u.self_filtered, u.sets,
                       u.crosstalk_pulses, u.valid_pixels, u.corrupted_pixels, u.colours);
  return o.str();
}

std::string sim_rates_csv(const std::vector<SimStudyResult>& runs) {
  std::ostringstream o;
  o << "schedule,sensor,sets,simulated_s,rate_hz,set_period_s,corrupted_share\n";
  for (const auto& r : runs)
    for (const auto& s : r.sensors)
      o << fmt::format("{},{},{},{:.3f},{:.3f},{:.5f},{:.5f}\n", r.schedule, s.sensor, s.sets, r.simulated_s, s.rate_hz,
                       r.set_period_s, s.corrupted_share);
  return o.str();
}

}  // namespace tinyline::hydrus_fitting::eval
