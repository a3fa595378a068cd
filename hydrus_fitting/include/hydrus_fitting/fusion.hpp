// SPDX-License-Identifier: Apache-2.0
// Fusion of the line scans of every sensor on the robot into one 2-D frame
// at the sensors' height (thesis 6.2.2: "we mount the laser at the same plane
// thus the laser distance data can be regressed to 2D expressions"), each
// scan placed with the joint angles at its own timestamp, and the self-filter
// of 6.2.3: points that fall on the robot's own links are removed using the
// robot model.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <tinyline/common/status.hpp>

#include "hydrus_fitting/robot_model.hpp"

namespace tinyline::hydrus_fitting {

/// Range noise SD of the sensor against distance, linearly interpolated and
/// held beyond the ends. Default: Table 3.1 (sim/config/fidelity/thesis_measured.yaml noise_vs_distance_cm,
/// 300 measurements of white paper per distance, after calibration).
struct RangeNoiseModel {
  std::vector<std::pair<double, double>> range_sd_m{
      {0.205, 0.003625}, {0.50, 0.006164}, {0.75, 0.006385}, {1.00, 0.010480}, {1.25, 0.019593}};
  [[nodiscard]] double sd_at(double range_m) const;
};

struct FusionParams {
  bool self_filter = true;
  /// Extra clearance around each link's footprint (length x width_m) [m]:
  /// covers the kinematic model's error and mixed pixels at the link's edge.
  double self_filter_margin_m = 0.03;
  RangeNoiseModel noise;
};
common::Status validate(const FusionParams& params);

/// One line scan in the robot description's terms (LineScan, converted).
struct ScanView {
  std::string_view sensor;            ///< name in the robot description
  std::int64_t stamp_ns = 0;          ///< the scan's time (joint states are taken there)
  std::span<const double> angle_rad;  ///< per pixel (LineScan.angles)
  std::span<const double> range_m;    ///< per pixel along its ray; NaN or <= 0 when invalid
};

/// What became of one scan. status: NotFound for a sensor not in the robot
/// description, InvalidArgument for a scan or joint vector of the wrong
/// length, the joint lookup's (NotFound or OutOfRange, joints says which
/// case) when there is no usable joint state at the scan's time.
struct ScanOutcome {
  common::Status status;
  JointLookupStatus joints = JointLookupStatus::kOk;
  int sensor = -1;        ///< index in the robot description
  int added = 0;          ///< points appended to the cloud
  int invalid = 0;        ///< pixels without a valid range (NaN, <= 0)
  int out_of_range = 0;   ///< outside the sensor's range_m
  int self_filtered = 0;  ///< on the robot's own links
  [[nodiscard]] bool ok() const { return status.ok(); }
};

/// The fused points in the robot (base) frame, with what the fitters need.
struct FusedCloud {
  std::vector<double> xy_m;            ///< x0, y0, x1, y1, ... in the base frame
  std::vector<double> sigma_m;         ///< range noise SD per point (RangeNoiseModel)
  std::vector<double> range_m;         ///< measured range per point
  std::vector<int> view_of_point;      ///< index into views
  std::vector<Eigen::Vector2d> views;  ///< per accepted scan: its sensor's origin in the base frame
  std::vector<int> view_sensor;        ///< per accepted scan: sensor index
  std::vector<std::int64_t> view_stamp_ns;
  int self_filtered = 0;
  [[nodiscard]] int size() const { return static_cast<int>(xy_m.size() / 2); }
  /// The points as a 2 x n matrix (no copy).
  [[nodiscard]] Eigen::Map<const Eigen::Matrix2Xd> points_m() const { return {xy_m.data(), 2, size()}; }
};

/// True when p (base frame) lies on a link's footprint grown by margin_m.
[[nodiscard]] bool on_robot(const RobotModel& model, const Kinematics& k, const Eigen::Vector2d& p, double margin_m);

/// Accumulates scans into one cloud. Reuses its buffers (clear() keeps the
/// capacity), so a node calls clear(), add() per sensor, then fits cloud().
class ScanFuser {
 public:
  explicit ScanFuser(const RobotModel& model, FusionParams params = {});

  void clear();
  /// Places one scan with the joint angles at its timestamp. A scan of an
  /// unknown sensor or without a usable joint state adds nothing and says why.
  /// `T_ref_base` then moves its points and its sensor's origin from the base
  /// frame at the scan's time into the cloud's frame (the base at the
  /// update's reference time: BasePoseBuffer::motion); the self-filter works
  /// before, with the links where they were at the scan's time.
  ScanOutcome add(const ScanView& scan, const JointStateBuffer& joints,
                  const Eigen::Isometry2d& T_ref_base = Eigen::Isometry2d::Identity());
  /// The same with the joint angles given (one per joint of the model).
  ScanOutcome add(const ScanView& scan, std::span<const double> joint_positions,
                  const Eigen::Isometry2d& T_ref_base = Eigen::Isometry2d::Identity());

  [[nodiscard]] const FusedCloud& cloud() const { return cloud_; }
  [[nodiscard]] const RobotModel& model() const { return *model_; }
  [[nodiscard]] const FusionParams& params() const { return params_; }

 private:
  ScanOutcome add_resolved(const ScanView& scan, int sensor, std::span<const double> q,
                           const Eigen::Isometry2d& T_ref_base);
  const RobotModel* model_;
  FusionParams params_;
  FusedCloud cloud_;
  // A sensor's pixel angles are the same scan after scan: their sines and
  // cosines are kept per sensor and reused while the angles match.
  struct Trig {
    std::vector<double> angle, c, s;
  };
  std::vector<Trig> trig_;
};

}  // namespace tinyline::hydrus_fitting
