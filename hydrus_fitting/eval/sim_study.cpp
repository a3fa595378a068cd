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

sim::ObjectId find_cylinder(const sim::SimulatedSystem& sys, const std::string& scene_path) {
  const auto id = sys.with_scene([](const sim::Scene& s) { return s.world.find("cylinder"); });
  if (!id) throw std::runtime_error("sim_study: scene " + scene_path + " has no object 'cylinder'");
  return *id;
}

std::vector<SensorRun> sensor_runs(const RobotModel& model, const SimulatedHydrus& robot) {
  std::vector<SensorRun> sensors(model.sensors().size());
  for (std::size_t s = 0; s < sensors.size(); ++s) {
    sensors[s].name = model.sensors()[s].name;
    sensors[s].sim_index = robot.sim_sensor(s);
  }
  return sensors;
}

SequencerParams sequencer_params(double set_s, double guard_s) {
  SequencerParams seq;
  seq.timing.set_period_s = set_s;
  seq.timing.guard_s = guard_s;
  return seq;
}

/// One simulated approach, slot by slot: who emits, what each emitting
/// sensor measures through the driver's processing, and the estimate.
class SimStudyRun {
 public:
  explicit SimStudyRun(const SimStudyParams& p)
      : p_(p),
        model_(RobotModel::load(p.robot_description)),
        sys_(sim::load_scene(p.scene_path)),
        robot_(sys_, model_),  // throws naming what the scene lacks
        truth_radius_(robot_.cylinder_radius_m()),
        cylinder_(find_cylinder(sys_, p.scene_path)),
        sensors_(sensor_runs(model_, robot_)),
        sp_(sys_.sensor(sensors_.front().sim_index).params()),
        pulses_(sp_.acquisition.raw_pulses),
        set_s_(pulses_.back() / sp_.emitter.pulse_rate_hz),
        processor_(drv::CalibrationModel::load(p.calibration_path), sim::driver_optics(sp_)),
        joints_(model_.joint_names(), JointBufferParams{0.05, 5.0}),
        base_poses_(BasePoseBufferParams{0.05, 5.0}),
        estimator_(model_),
        sequencer_(model_, sequencer_params(set_s_, p.guard_s)),
        next_joint_t_(p.start_s) {}

  SimStudyResult run() {
    SimStudyResult out;
    out.schedule = p_.schedule;
    out.set_period_s = set_s_;
    const double end = p_.end_s < 0.0 ? p_.approach.duration_s() : std::min(p_.end_s, p_.approach.duration_s());
    const double slot_s = p_.schedule == "all_on" ? set_s_ : set_s_ + p_.guard_s;
    if (p_.schedule == "all_on")
      for (const auto& s : sensors_) sys_.set_emitting(s.sim_index, true, p_.start_s);
    for (double t = p_.start_s; t + set_s_ <= end + 1e-9; t += slot_s) out.updates.push_back(step(t));
    out.simulated_s = end - p_.start_s;
    out.sensors = rates(out.simulated_s);
    return out;
  }

 private:
  /// The slot starting at t.
  SimUpdate step(double t) {
    // The robot stands where it is in the middle of the set: the time the
    // scan is stamped with, and the mean of its pose over the accumulation.
    const RobotPose2D pose = approach_pose(p_.approach, t + 0.5 * set_s_);
    robot_.place(pose);
    feed_joints_until(t + set_s_);
    SimUpdate u;
    const std::vector<int> active = emitters(pose, u.colours);
    switch_emitters(active, t);
    u.t_s = t + set_s_;
    for (const int s : active) measure(sensors_[static_cast<std::size_t>(s)], t, u);
    ++slot_;
    estimate(u);
    return u;
  }

  /// The joint stream: a JointState every 10 ms, as a flight controller sends.
  void feed_joints_until(double t) {
    for (; next_joint_t_ <= t + 1e-9; next_joint_t_ += 0.01) {
      const RobotPose2D q = approach_pose(p_.approach, next_joint_t_);
      joints_.add(to_ns(next_joint_t_), model_.joint_names(), q.joints_rad);
      const Eigen::Isometry2d T = q.T_world_base();
      base_poses_.add(to_ns(next_joint_t_), T.translation(), std::atan2(T.linear()(1, 0), T.linear()(0, 0)));
    }
  }

  /// Who emits in this slot, and how many slots the schedule has.
  std::vector<int> emitters(const RobotPose2D& pose, int& colours) {
    const int n = static_cast<int>(sensors_.size());
    std::vector<int> active;
    colours = 1;
    if (p_.schedule == "all_on") {
      for (int s = 0; s < n; ++s) active.push_back(s);
    } else if (p_.schedule == "time_slicing") {
      active.push_back(slot_ % n);
      colours = n;
    } else {
      if (sequencer_.update(pose.joints_rad, object_)) slot_ = 0;  // a new schedule starts at its first slot
      const Schedule& sch = sequencer_.schedule();
      colours = sch.slot_count();
      active = sch.slots[static_cast<std::size_t>(slot_ % sch.slot_count())];
    }
    return active;
  }

  void switch_emitters(const std::vector<int>& active, double t) {
    if (p_.schedule == "all_on") return;
    for (std::size_t s = 0; s < sensors_.size(); ++s) {
      const bool on = std::find(active.begin(), active.end(), static_cast<int>(s)) != active.end();
      sys_.set_emitting(sensors_[s].sim_index, on, t);
      if (on) sys_.set_emitting(sensors_[s].sim_index, false, t + set_s_);
    }
  }

  /// One set of sensor r from t, through the driver's processing.
  void measure(SensorRun& r, double t, SimUpdate& u) {
    // The scene's sensors are one calibrated unit (same per-pixel
    // constants): the set index alone seeds the noise, so each sensor gets
    // its own index range to keep their noise independent.
    const std::uint64_t index = p_.seed * 1000003ULL + (r.sim_index + 1) * 100000007ULL + r.index++;
    const sim::SensorSet set = sys_.measure(r.sim_index, t, pulses_, index);
    drv::RawSet raw;
    raw.frames = sim::raw_frames(set);
    const drv::ProcessedScan scan = processor_.process(raw, sys_.sensor_time(t));
    r.angle.assign(processor_.angles_rad().begin(), processor_.angles_rad().end());
    r.range.resize(drv::kPixels);
    for (std::size_t i = 0; i < drv::kPixels; ++i) {
      const bool ok = scan.status[i] == drv::PixelStatus::kValid;
      r.range[i] = ok ? static_cast<double>(scan.distance_m[i]) : std::numeric_limits<double>::quiet_NaN();
      // Corruption is judged on the cylinder's clean pixels (not mixed with the background).
      if (!ok || i >= set.truth.size() || set.truth[i].object != cylinder_ || set.truth[i].mixed) continue;
      ++u.valid_pixels;
      ++r.valid;
      if (std::abs(r.range[i] - set.truth[i].range_m) > p_.corrupt_threshold_m) {
        ++u.corrupted_pixels;
        ++r.corrupted;
      }
    }
    r.stamp_ns = to_ns(t + 0.5 * set_s_);  // the middle of the accumulation
    r.have = true;
    ++r.sets;
    ++u.sets;
    u.crosstalk_pulses += set.crosstalk_pulses;
  }

  /// The estimate from every sensor's newest scan, scored against the truth.
  void estimate(SimUpdate& u) {
    std::vector<ScanView> views;
    for (const auto& r : sensors_)
      if (r.have) views.push_back({r.name, r.stamp_ns, r.angle, r.range});
    const CircleEstimate e = estimator_.estimate(views, joints_, p_.base_motion ? &base_poses_ : nullptr);
    // The truth in the robot frame at the newest scan's time.
    const RobotPose2D pose_now = approach_pose(p_.approach, static_cast<double>(e.stamp_ns) * 1e-9);
    const Eigen::Vector2d truth = robot_.centre_in_base(pose_now);
    u.status = static_cast<int>(e.fit.detail);
    u.true_x_m = truth.x();
    u.true_y_m = truth.y();
    u.points = e.points;
    u.self_filtered = e.self_filtered;
    if (!e.fit.ok()) return;
    u.inliers = e.fit.points_used;
    u.centre_x_m = e.fit.circle.centre_m.x();
    u.centre_y_m = e.fit.circle.centre_m.y();
    u.radius_m = e.fit.circle.radius_m;
    u.centre_error_m = (e.fit.circle.centre_m - truth).norm();
    u.radius_error_m = e.fit.circle.radius_m - truth_radius_;
    object_ = e.fit.circle;
  }

  std::vector<SimSensorRate> rates(double simulated_s) const {
    std::vector<SimSensorRate> out;
    for (const auto& r : sensors_) {
      SimSensorRate rate;
      rate.sensor = r.name;
      rate.sets = r.sets;
      rate.rate_hz = simulated_s > 0.0 ? r.sets / simulated_s : 0.0;
      rate.corrupted_share = r.valid > 0 ? static_cast<double>(r.corrupted) / static_cast<double>(r.valid) : 0.0;
      out.push_back(rate);
    }
    return out;
  }

  const SimStudyParams& p_;
  const RobotModel model_;
  sim::SimulatedSystem sys_;
  SimulatedHydrus robot_;
  const double truth_radius_;
  const sim::ObjectId cylinder_;
  std::vector<SensorRun> sensors_;
  const sim::SensorParams sp_;
  const std::vector<int> pulses_;
  const double set_s_;
  const drv::ScanProcessor processor_;
  JointStateBuffer joints_;
  BasePoseBuffer base_poses_;
  CircleEstimator estimator_;
  Sequencer sequencer_;
  std::optional<Circle> object_;
  double next_joint_t_;
  int slot_ = 0;
};

}  // namespace

SimStudyResult sim_study(const SimStudyParams& p) {
  if (p.schedule != "all_on" && p.schedule != "time_slicing" && p.schedule != "colouring")
    throw std::invalid_argument("sim_study: schedule must be all_on, time_slicing or colouring, got '" + p.schedule +
                                "'");
  if (const common::Status why = p.approach.validate(); !why.ok())
    throw std::invalid_argument("sim_study: " + why.message);
  return SimStudyRun(p).run();
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
