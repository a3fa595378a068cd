// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/fusion.hpp"

#include "hydrus_fitting/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace tinyline::hydrus_fitting {

double RangeNoiseModel::sd_at(double range_m) const {
  if (range_sd_m.empty()) return 0.0;
  if (range_m <= range_sd_m.front().first) return range_sd_m.front().second;
  if (range_m >= range_sd_m.back().first) return range_sd_m.back().second;
  // The first entry beyond range_m (a handful of entries: a linear scan beats
  // a binary search, and every fused point asks).
  auto hi = range_sd_m.begin() + 1;
  while (!(range_m < hi->first)) ++hi;
  const auto lo = std::prev(hi);
  const double w = (range_m - lo->first) / (hi->first - lo->first);
  return (1.0 - w) * lo->second + w * hi->second;
}

namespace {

/// A link's footprint as a test in its own frame: x in [-m, L + m], |y| <= w/2 + m,
/// behind a base-frame bounding box that rejects most points with four compares.
struct Footprint {
  Eigen::Isometry2d T_link_base;
  double x_max, half_width;
  Eigen::Vector2d lo, hi;  // bounding box in the base frame
};

std::vector<Footprint> footprints(const RobotModel& model, const Kinematics& k, double margin_m) {
  std::vector<Footprint> f;
  f.reserve(model.links().size());
  for (std::size_t i = 0; i < model.links().size(); ++i) {
    const auto& l = model.links()[i];
    Footprint fp{k.T_base_link[i].inverse(), l.length_m + margin_m, 0.5 * l.width_m + margin_m, {}, {}};
    fp.lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    fp.hi = -fp.lo;
    for (const double x : {-margin_m, fp.x_max})
      for (const double y : {-fp.half_width, fp.half_width}) {
        const Eigen::Vector2d c = k.T_base_link[i] * Eigen::Vector2d(x, y);
        fp.lo = fp.lo.cwiseMin(c);
        fp.hi = fp.hi.cwiseMax(c);
      }
    f.push_back(fp);
  }
  return f;
}

bool inside(const std::vector<Footprint>& fs, const Eigen::Vector2d& p, double margin_m) {
  for (const auto& f : fs) {
    if (p.x() < f.lo.x() || p.y() < f.lo.y() || p.x() > f.hi.x() || p.y() > f.hi.y()) continue;
    const Eigen::Vector2d q = f.T_link_base * p;
    if (q.x() >= -margin_m && q.x() <= f.x_max && std::abs(q.y()) <= f.half_width) return true;
  }
  return false;
}

}  // namespace

bool on_robot(const RobotModel& model, const Kinematics& k, const Eigen::Vector2d& p, double margin_m) {
  return inside(footprints(model, k, margin_m), p, margin_m);
}

common::Status validate(const FusionParams& params) { return common::within_table(params); }

ScanFuser::ScanFuser(const RobotModel& model, FusionParams params)
    : model_(&model), params_(std::move(params)), trig_(model.sensors().size()) {
  if (const common::Status v = validate(params_); !v.ok()) throw std::invalid_argument("fusion: " + v.message);
}

void ScanFuser::clear() {
  // (the per-sensor trig cache survives: it depends on the angles only)
  cloud_.xy_m.clear();
  cloud_.sigma_m.clear();
  cloud_.range_m.clear();
  cloud_.view_of_point.clear();
  cloud_.views.clear();
  cloud_.view_sensor.clear();
  cloud_.view_stamp_ns.clear();
  cloud_.self_filtered = 0;
}

ScanOutcome ScanFuser::add(const ScanView& scan, const JointStateBuffer& joints, const Eigen::Isometry2d& T_ref_base) {
  ScanOutcome out;
  const auto sensor = model_->sensor_index(scan.sensor);
  if (!sensor) {
    std::string known;
    for (const auto& s : model_->sensors()) known += (known.empty() ? "" : ", ") + s.name;
    out.status = common::Status::not_found(fmt::format("sensor '{}' is not in the robot description '{}' (it has: {})",
                                                       scan.sensor, model_->name(), known));
    return out;
  }
  if (joints.joint_names() != model_->joint_names()) {
    out.status = common::Status::invalid("joint buffer was made for other joints than the robot model's");
    return out;
  }
  const JointLookup q = joints.at(scan.stamp_ns);
  if (!q.ok()) {
    out.status = q.status;
    out.joints = q.detail;
    out.sensor = *sensor;
    return out;
  }
  return add_resolved(scan, *sensor, q.positions, T_ref_base);
}

ScanOutcome ScanFuser::add(const ScanView& scan, std::span<const double> joint_positions,
                           const Eigen::Isometry2d& T_ref_base) {
  ScanOutcome out;
  const auto sensor = model_->sensor_index(scan.sensor);
  if (!sensor) {
    out.status = common::Status::not_found(
        fmt::format("sensor '{}' is not in the robot description '{}'", scan.sensor, model_->name()));
    return out;
  }
  if (joint_positions.size() != model_->joint_names().size()) {
    out.status = common::Status::invalid(
        fmt::format("{} joint positions for {} joints", joint_positions.size(), model_->joint_names().size()));
    return out;
  }
  return add_resolved(scan, *sensor, joint_positions, T_ref_base);
}

ScanOutcome ScanFuser::add_resolved(const ScanView& scan, int sensor, std::span<const double> q,
                                    const Eigen::Isometry2d& T_ref_base) {
  ScanOutcome out;
  out.sensor = sensor;
  if (scan.angle_rad.size() != scan.range_m.size()) {
    out.status = common::Status::invalid(fmt::format("scan of '{}' has {} angles but {} ranges", scan.sensor,
                                                     scan.angle_rad.size(), scan.range_m.size()));
    return out;
  }
  const Kinematics k = model_->forward(q);
  const SensorSpec& spec = model_->sensors()[static_cast<std::size_t>(sensor)];
  const Eigen::Isometry2d& T = k.T_base_sensor[static_cast<std::size_t>(sensor)];
  const double margin = params_.self_filter_margin_m;
  const auto fps = params_.self_filter ? footprints(*model_, k, margin) : std::vector<Footprint>{};
  const int view = static_cast<int>(cloud_.views.size());
  const Eigen::Matrix2d R = T.linear();
  const Eigen::Vector2d t = T.translation();
  const double side = spec.line_axis_left ? 1.0 : -1.0;
  const Eigen::Matrix2d Rm = T_ref_base.linear();
  const Eigen::Vector2d tm = T_ref_base.translation();

  Trig& tr = trig_[static_cast<std::size_t>(sensor)];
  if (!std::equal(tr.angle.begin(), tr.angle.end(), scan.angle_rad.begin(), scan.angle_rad.end())) {
    tr.angle.assign(scan.angle_rad.begin(), scan.angle_rad.end());
    tr.c.resize(tr.angle.size());
    tr.s.resize(tr.angle.size());
    for (std::size_t i = 0; i < tr.angle.size(); ++i) {
      tr.c[i] = std::cos(tr.angle[i]);
      tr.s[i] = side * std::sin(tr.angle[i]);
    }
  }
  cloud_.xy_m.reserve(cloud_.xy_m.size() + 2 * scan.range_m.size());
  for (std::size_t i = 0; i < scan.range_m.size(); ++i) {
    const double r = scan.range_m[i];
    const double a = scan.angle_rad[i];
    if (!std::isfinite(r) || !(r > 0.0) || !std::isfinite(a)) {
      ++out.invalid;
      continue;
    }
    if (r < spec.min_range_m || r > spec.max_range_m) {
      ++out.out_of_range;
      continue;
    }
    const Eigen::Vector2d p = t + R * Eigen::Vector2d(r * tr.c[i], r * tr.s[i]);
    if (!fps.empty() && inside(fps, p, margin)) {
      ++out.self_filtered;
      continue;
    }
    const Eigen::Vector2d pr = tm + Rm * p;
    cloud_.xy_m.push_back(pr.x());
    cloud_.xy_m.push_back(pr.y());
    cloud_.sigma_m.push_back(params_.noise.sd_at(r));
    cloud_.range_m.push_back(r);
    cloud_.view_of_point.push_back(view);
    ++out.added;
  }
  cloud_.views.push_back(T_ref_base * t);
  cloud_.view_sensor.push_back(sensor);
  cloud_.view_stamp_ns.push_back(scan.stamp_ns);
  cloud_.self_filtered += out.self_filtered;
  return out;
}

}  // namespace tinyline::hydrus_fitting
