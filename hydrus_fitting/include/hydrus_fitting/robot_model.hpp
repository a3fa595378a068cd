// SPDX-License-Identifier: Apache-2.0
// The planar multi-link robot (Hydrus, thesis 6.2): a serial chain of links
// in one plane joined by yaw joints, with laser line sensors mounted on the
// links at one height. Loaded from a YAML robot description:
//
//   name: hydrus4
//   links:                          # link i+1 hangs on a joint at the far end of link i
//     - {name: link1, length_m: 0.6, width_m: 0.1}
//     - {name: link2, length_m: 0.6, width_m: 0.1, joint: {name: joint1, limits_deg: [-95, 95]}}
//   sensors:
//     - name: laser1
//       link: link1
//       position_m: [0.3, 0.06]     # in the link frame: x along the link, y to its left
//       yaw_deg: 90                 # optical axis in the link frame
//       height_m: 0.0               # above the link plane; every sensor at the same height
//       focal_mm: 3.6               # receiver lens: field of view from the 5.12 mm pixel line
//       fan_half_angle_deg: 38      # emitter fan
//       line_axis: left             # pixel angles grow to the left (or right) of the axis
//       range_m: [0.05, 2.0]
//
// Frames: link i's frame has its origin at the link's near end (its joint)
// and x along the link. The robot frame ("base") is link 1's frame.
//   T_base_link{i+1} = T_base_link{i} * Trans(length_i, 0) * Rot(q_i)
// Errors while loading name the file, line and field (RobotModelError).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include <tinyline/common/status.hpp>

namespace tinyline::hydrus_fitting {

/// The largest robot description read [bytes] (the shipped one is under 2 KB).
inline constexpr std::uint64_t kMaxRobotDescriptionBytes = 1u << 20;

/// A bad robot description: "file:line: field: reason".
class RobotModelError : public std::runtime_error {
 public:
  RobotModelError(std::string file, int line, std::string field, const std::string& reason);
  const std::string& file() const { return file_; }
  int line() const { return line_; }  ///< 1-based, 0 when unknown
  const std::string& field() const { return field_; }

 private:
  std::string file_;
  int line_;
  std::string field_;
};

struct LinkSpec {
  std::string name;
  double length_m = 0.6;
  double width_m = 0.1;         ///< footprint across the link, for the self-filter
  std::string joint;            ///< joint at its near end (empty for the first link)
  double joint_min_rad = -3.2;  ///< joint limits (first link: unused)
  double joint_max_rad = 3.2;
};

struct SensorSpec {
  std::string name;
  int link = 0;                                          ///< index into links
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();  ///< in the link frame
  double yaw_rad = 0.0;                                  ///< optical axis in the link frame
  double height_m = 0.0;
  double focal_mm = 3.6;
  double sensor_length_mm = 5.12;     ///< length of the 256 effective pixels
  double fan_half_angle_rad = 0.663;  ///< 38 deg
  bool line_axis_left = true;         ///< +pixel angle is to the left of the optical axis
  double min_range_m = 0.05;
  double max_range_m = 2.0;

  /// Half the receiver's field of view along the line [rad].
  [[nodiscard]] double fov_half_angle_rad() const;
  /// The sensor's 2-D pose in its link's frame (x = optical axis).
  [[nodiscard]] Eigen::Isometry2d T_link_sensor() const;
  /// A pixel's ray in the sensor's 2-D frame (x forward, y left) for a pixel
  /// angle in its x-z plane (LineScan.angles).
  [[nodiscard]] Eigen::Vector2d ray(double pixel_angle_rad) const;
};

/// Link and sensor poses for one joint configuration.
struct Kinematics {
  std::vector<Eigen::Isometry2d> T_base_link;    ///< per link
  std::vector<Eigen::Isometry2d> T_base_sensor;  ///< per sensor (x = optical axis)
};

class RobotModel {
 public:
  /// Reads a regular file of at most kMaxRobotDescriptionBytes (a FIFO or a
  /// device is refused). Throws RobotModelError (file, line, field) on a bad description.
  [[nodiscard]] static RobotModel load(const std::string& path);
  [[nodiscard]] static RobotModel parse(const std::string& yaml_text, const std::string& source_name = "<string>");
  /// Builds a model in code; throws std::invalid_argument naming the bad entry.
  RobotModel(std::string name, std::vector<LinkSpec> links, std::vector<SensorSpec> sensors);

  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] const std::vector<LinkSpec>& links() const { return links_; }
  [[nodiscard]] const std::vector<SensorSpec>& sensors() const { return sensors_; }
  /// Joint names in chain order (one per link after the first).
  [[nodiscard]] const std::vector<std::string>& joint_names() const { return joints_; }
  [[nodiscard]] std::optional<int> sensor_index(std::string_view name) const;
  [[nodiscard]] std::optional<int> joint_index(std::string_view name) const;
  /// Height of the sensing plane (every sensor's height_m).
  [[nodiscard]] double sensor_height_m() const { return sensors_.empty() ? 0.0 : sensors_.front().height_m; }

  /// Forward kinematics; `q` has one angle per joint [rad] (size checked:
  /// throws std::invalid_argument on a mismatch).
  [[nodiscard]] Kinematics forward(std::span<const double> q) const;

 private:
  RobotModel() = default;
  void validate() const;
  std::string name_;
  std::vector<LinkSpec> links_;
  std::vector<SensorSpec> sensors_;
  std::vector<std::string> joints_;
};

// ---------------------------------------------------------------------------- joint states

struct JointBufferParams {
  /// A scan may be this much newer than the newest joint sample (or older
  /// than the oldest) and still use it held constant; beyond, the lookup is
  /// kStale (kBeforeHistory).
  double tolerance_s = 0.02;
  /// Samples older than this behind the newest are forgotten.
  double history_s = 2.0;
};
common::Status validate(const JointBufferParams& params);

/// Why a joint lookup failed, finer than its Status's code (NotFound for
/// kNoData, OutOfRange for the others): a joint not heard from yet is waited
/// for, one that stopped publishing is a fault, a scan older than the history
/// is dropped. The fusion reports it per scan (ScanOutcome::joints).
enum class JointLookupStatus : std::uint8_t {
  kOk = 0,
  kNoData,         ///< a joint has no sample yet
  kStale,          ///< the newest sample of a joint is older than the scan beyond the tolerance
  kBeforeHistory,  ///< the scan is older than the oldest kept sample beyond the tolerance
};
[[nodiscard]] const char* to_string(JointLookupStatus s);

struct JointLookup {
  common::Status status{common::StatusCode::NotFound, ""};  ///< the message names the joint and the times
  JointLookupStatus detail = JointLookupStatus::kNoData;    ///< the finer case, kOk when ok
  std::vector<double> positions;                            ///< per joint of the model [rad], interpolated
  double max_gap_s = 0.0;  ///< largest time to the nearest sample used, over the joints
  [[nodiscard]] bool ok() const { return status.ok(); }
};

struct JointAddResult {
  int used = 0;        ///< values stored
  int unknown = 0;     ///< names not in the model (ignored)
  int non_finite = 0;  ///< NaN/inf positions (ignored)
  std::string reason;  ///< set when something was ignored
};

/// Per-joint time series of positions (a JointState may carry a subset of the
/// joints, or others, as in ROS); linear interpolation at any stamp.
class JointStateBuffer {
 public:
  explicit JointStateBuffer(std::vector<std::string> joint_names, JointBufferParams params = {});

  /// Adds one JointState sample. Samples may arrive out of order; a second
  /// sample at the same stamp replaces the first.
  JointAddResult add(std::int64_t stamp_ns, std::span<const std::string> names, std::span<const double> positions);
  /// Positions at `stamp_ns`.
  [[nodiscard]] JointLookup at(std::int64_t stamp_ns) const;
  [[nodiscard]] const std::vector<std::string>& joint_names() const { return names_; }
  void clear();

 private:
  struct Sample {
    std::int64_t t_ns;
    double q;
  };
  std::vector<std::string> names_;
  JointBufferParams params_;
  std::vector<std::deque<Sample>> series_;
};

}  // namespace tinyline::hydrus_fitting
