// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/base_motion.hpp"

#include "hydrus_fitting/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include <fmt/format.h>

namespace tinyline::hydrus_fitting {

common::Status validate(const BasePoseBufferParams& params) { return common::within_table(params); }

BasePoseBuffer::BasePoseBuffer(BasePoseBufferParams params) : params_(params) {
  if (const common::Status v = validate(params_); !v.ok()) throw std::invalid_argument("BasePoseBuffer: " + v.message);
}

bool BasePoseBuffer::add(std::int64_t stamp_ns, const Eigen::Vector2d& xy_m, double yaw_rad) {
  if (!std::isfinite(xy_m.x()) || !std::isfinite(xy_m.y()) || !std::isfinite(yaw_rad)) return false;
  const Pose p{stamp_ns, xy_m.x(), xy_m.y(), yaw_rad};
  const auto it = std::lower_bound(poses_.begin(), poses_.end(), stamp_ns,
                                   [](const Pose& a, std::int64_t t) { return a.t_ns < t; });
  if (it != poses_.end() && it->t_ns == stamp_ns) {
    *it = p;
  } else {
    poses_.insert(it, p);
  }
  const auto horizon = poses_.back().t_ns - static_cast<std::int64_t>(params_.history_s * 1e9);
  while (poses_.size() > 2 && poses_.front().t_ns < horizon) poses_.pop_front();
  return true;
}

BasePoseLookup BasePoseBuffer::at(std::int64_t stamp_ns) const {
  BasePoseLookup out;
  if (poses_.empty()) {
    out.status.message = "no base pose received yet";
    return out;
  }
  auto make = [&](double x, double y, double yaw) {
    out.status = {};
    out.T_fixed_base = Eigen::Translation2d(x, y) * Eigen::Rotation2Dd(yaw);
    return out;
  };
  if (stamp_ns >= poses_.back().t_ns || stamp_ns <= poses_.front().t_ns) {
    const bool after = stamp_ns >= poses_.back().t_ns;
    const Pose& end = after ? poses_.back() : poses_.front();
    const double gap = 1e-9 * static_cast<double>(after ? stamp_ns - end.t_ns : end.t_ns - stamp_ns);
    if (gap > params_.tolerance_s) {
      out.status.message =
          fmt::format("the {} base pose is {:.3f} s {} the scan (tolerance {:.3f} s)", after ? "newest" : "oldest kept",
                      gap, after ? "older than" : "newer than", params_.tolerance_s);
      return out;
    }
    return make(end.x, end.y, end.yaw);
  }
  const auto hi = std::upper_bound(poses_.begin(), poses_.end(), stamp_ns,
                                   [](std::int64_t t, const Pose& p) { return t < p.t_ns; });
  const auto lo = std::prev(hi);
  const double w = static_cast<double>(stamp_ns - lo->t_ns) / static_cast<double>(hi->t_ns - lo->t_ns);
  const double dyaw = std::remainder(hi->yaw - lo->yaw, 2.0 * std::numbers::pi);
  return make((1.0 - w) * lo->x + w * hi->x, (1.0 - w) * lo->y + w * hi->y, lo->yaw + w * dyaw);
}

BasePoseLookup BasePoseBuffer::motion(std::int64_t from_ns, std::int64_t to_ns) const {
  const BasePoseLookup from = at(from_ns);
  if (!from.status.ok()) return from;
  BasePoseLookup to = at(to_ns);
  if (!to.status.ok()) return to;
  to.T_fixed_base = to.T_fixed_base.inverse() * from.T_fixed_base;
  return to;
}

}  // namespace tinyline::hydrus_fitting
