// SPDX-License-Identifier: Apache-2.0
// The robot base's own motion between the scans of one update: the joint
// states place each scan in the base frame at its own time, but while the
// robot flies in, the base frame itself moves (up to 1.5 cm over one
// schedule cycle at 0.125 m/s). With the base's pose in a fixed frame
// (odometry, motion capture, the flight controller's estimate) each scan is
// moved into the base frame at the update's reference time (its newest
// scan) before fusing, so that all scans see the object in one place.
#pragma once

#include <cstdint>
#include <deque>
#include <string>

#include <Eigen/Geometry>

#include <tinyline/common/status.hpp>

namespace tinyline::hydrus_fitting {

struct BasePoseBufferParams {
  /// A lookup may be this much beyond the newest (or before the oldest) pose
  /// and still use it held constant; beyond, it fails with a reason [s].
  double tolerance_s = 0.02;
  double history_s = 2.0;  ///< poses older than this behind the newest are forgotten [s]
};
common::Status validate(const BasePoseBufferParams& params);

struct BasePoseLookup {
  /// OutOfRange: no pose yet, or the stamp beyond the tolerance of the poses held.
  common::Status status = common::Status(common::StatusCode::OutOfRange, "not looked up");
  Eigen::Isometry2d T_fixed_base = Eigen::Isometry2d::Identity();  ///< the base in the fixed frame
};

/// Time-stamped planar base poses (x, y, yaw in a fixed frame), interpolated
/// linearly (yaw along the shorter way round).
class BasePoseBuffer {
 public:
  explicit BasePoseBuffer(BasePoseBufferParams params = {});

  /// Adds one pose; false (and nothing added) when a value is not finite.
  /// Out-of-order poses are placed by time; one at an existing stamp replaces it.
  bool add(std::int64_t stamp_ns, const Eigen::Vector2d& xy_m, double yaw_rad);
  [[nodiscard]] BasePoseLookup at(std::int64_t stamp_ns) const;
  /// The transform from the base frame at `from_ns` to the base frame at
  /// `to_ns`: a point seen at from_ns, where it is relative to the base at to_ns.
  [[nodiscard]] BasePoseLookup motion(std::int64_t from_ns, std::int64_t to_ns) const;
  [[nodiscard]] bool empty() const { return poses_.empty(); }
  void clear() { poses_.clear(); }

 private:
  struct Pose {
    std::int64_t t_ns;
    double x, y, yaw;
  };
  BasePoseBufferParams params_;
  std::deque<Pose> poses_;
};

}  // namespace tinyline::hydrus_fitting
