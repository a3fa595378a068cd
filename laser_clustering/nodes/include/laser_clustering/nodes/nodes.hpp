// SPDX-License-Identifier: Apache-2.0
// The laser_clustering nodes: thin shells that declare parameters (defaults
// from the core's structs), convert tinyline_msgs/LineScan to the core's
// LineScan, call the core and publish. Topic names are generic; launch files
// remap them. Construct one directly to embed it, or by name through
// register_nodes().
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/point_stamped.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/tinyline_msgs/alignment_result.hpp>
#include <tinyline/msg/tinyline_msgs/expected_tomatoes.hpp>
#include <tinyline/msg/tinyline_msgs/line_clusters.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/pedicel_detection.hpp>
#include <tinyline/msg/tinyline_msgs/pedicel_layout.hpp>
#include <tinyline/msg/tinyline_msgs/truss_registration.hpp>

#include "laser_clustering/alignment_search.hpp"
#include "laser_clustering/pedicel_finder.hpp"
#include "laser_clustering/reflectance_clustering.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "laser_clustering/two_stage.hpp"

namespace tinyline::laser_clustering {

namespace detail {
/// What the line and reflectance clusterer nodes share: `min_reflectance`,
/// scan in, clusters out, and a scan the conversion refuses published as an
/// empty result whose note says why. Each node says only how it clusters.
class ScanToClusters {
 public:
  using Cluster = std::function<void(const LineScan&, tinyline_msgs::msg::LineClusters&)>;
  ScanToClusters(bus::Node& node, Cluster cluster);

 private:
  void on_scan(const tinyline_msgs::msg::LineScan& msg);
  bus::Node& node_;
  Cluster cluster_;
  LineScan scan_;  // reused buffers
  double min_reflectance_ = 0.0;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::LineClusters>> pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> sub_;
};
}  // namespace detail

/// scan (tinyline_msgs/LineScan) -> clusters (tinyline_msgs/LineClusters):
/// two-stage clustering of thesis 4.4.2.
class LineClustererNode : public bus::Node {
 public:
  explicit LineClustererNode(bus::NodeOptions options);

 private:
  LineScanClusterer clusterer_;
  TwoStageResult objects_;  // reused buffers
  detail::ScanToClusters topics_;
};

/// scan -> pedicel (tinyline_msgs/PedicelDetection) and clusters: the
/// pedicel finder of 4.4.2 / 4.5. An optional expected_pedicel
/// (geometry_msgs/PointStamped in the scan's frame, from the vision side)
/// replaces the blade throat as the expected position while it is recent;
/// or expected_layout (tinyline_msgs/PedicelLayout), which adds where the
/// truss's other pedicels are expected, the previous scan's runners-up and a
/// gate (a pedicel far from every expected place is nothing to cut). The
/// newest of the two counts.
class PedicelFinderNode : public bus::Node {
 public:
  explicit PedicelFinderNode(bus::NodeOptions options);

 private:
  void on_scan(const tinyline_msgs::msg::LineScan& msg);
  LineScanClusterer clusterer_;
  TwoStageResult objects_;  // reused buffers
  PedicelFinderParams finder_;
  double expectation_sd_m_ = 0.0;
  double expectation_max_age_s_ = 0.0;
  // The newest expectation from either topic, with its stamp.
  std::optional<std::pair<bus::Time, PedicelExpectation>> expected_;
  LineScan scan_;
  double min_reflectance_ = 0.0;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::PedicelDetection>> pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::LineClusters>> clusters_pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> sub_;
  std::shared_ptr<bus::Subscription<geometry_msgs::msg::PointStamped>> expected_sub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::PedicelLayout>> layout_sub_;
};

/// scan + expected_tomatoes (tinyline_msgs/ExpectedTomatoes: the vision's
/// tomatoes in the scan's laser frame) -> truss_registration
/// (tinyline_msgs/TrussRegistration): the tomato look. With the laser plane
/// lowered through the truss's tomatoes, the vision's tomatoes fitted to the
/// scan give the vision's common offset (register_tomatoes), which moves and
/// gates the pedicel expectation (PedicelLayout's expected and gate_sd).
/// The newest expected tomatoes serve every scan of their frame within
/// expectation_max_age_s of their stamp; a scan without such tomatoes is not
/// registered (nothing was asked): it is counted, and each kind of miss (none
/// yet, another frame, stale) is warned about once.
class TomatoRegistrationNode : public bus::Node {
 public:
  explicit TomatoRegistrationNode(bus::NodeOptions options);

  /// Scans that found no expected tomatoes of their frame and age.
  [[nodiscard]] std::uint64_t scans_without_tomatoes() const { return scans_without_tomatoes_; }

 private:
  void on_tomatoes(const tinyline_msgs::msg::ExpectedTomatoes& msg);
  void on_scan(const tinyline_msgs::msg::LineScan& msg);
  enum class Miss { kNoneYet, kOtherFrame, kStale };
  void skip(Miss miss, const std::string& why);
  TomatoRegistrationParams params_;
  double expectation_max_age_s_ = 0.0;
  double min_reflectance_ = 0.0;
  struct Expected {
    bus::Time stamp;
    std::string frame_id;
    std::vector<ExpectedTomato> tomatoes;
    double max_shift_m = 0.0;  // the message's; 0: the node's
    std::string malformed;     // what is wrong with the message, when it is
  };
  std::optional<Expected> expected_;
  std::uint64_t scans_without_tomatoes_ = 0;
  std::array<bool, 3> warned_{};  // per Miss
  LineScan scan_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::TrussRegistration>> pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> sub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::ExpectedTomatoes>> tomatoes_sub_;
};

/// scan -> clusters: DBSCAN on position and reflectance (thesis 5.3, Fig. 5.8).
class ReflectanceClustererNode : public bus::Node {
 public:
  explicit ReflectanceClustererNode(bus::NodeOptions options);

 private:
  ReflectanceClusteringParams params_;
  detail::ScanToClusters topics_;
};

/// scan + joint_states (sensor_msgs/JointState with the gripper's pitch
/// joint) -> alignment (tinyline_msgs/AlignmentResult) after every scan: the
/// pitch of maximum surface reflectance over the samples of the last
/// window_s seconds (thesis 5.3.2).
class AlignmentSearchNode : public bus::Node {
 public:
  explicit AlignmentSearchNode(bus::NodeOptions options);

 private:
  void on_joints(const sensor_msgs::msg::JointState& msg);
  void on_scan(const tinyline_msgs::msg::LineScan& msg);
  SurfaceReflectanceParams surface_;
  AlignmentParams params_;
  std::string joint_;
  double window_s_ = 0.0;
  double max_joint_age_s_ = 0.0;
  std::deque<std::pair<bus::Time, double>> pitch_;  // joint history (stamp, rad)
  std::deque<std::pair<bus::Time, AlignmentSample>> samples_;
  LineScan scan_;
  double min_reflectance_ = 0.0;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::AlignmentResult>> pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> sub_;
  std::shared_ptr<bus::Subscription<sensor_msgs::msg::JointState>> joints_sub_;
};

/// The gripper's side of 5.3.2: sweeps the pitch joint (joint_command,
/// sensor_msgs/JointState with one position) from from_deg to to_deg in
/// step_deg steps, holding each for dwell_s, then takes the alignment
/// search's newest result (alignment) and, when it found a peak, commands
/// that pitch: the gripper faces the tool squarely and can grasp. The result
/// it acted on goes out once on `aligned` (a copy of the AlignmentResult;
/// AT_SWEEP_EDGE / NO_PEAK / INVALID_INPUT leave the gripper at the sweep's
/// end, and `reason` says why).
class PitchSweepNode : public bus::Node {
 public:
  explicit PitchSweepNode(bus::NodeOptions options);

  enum class State { kSweeping, kDone };
  [[nodiscard]] State state() const { return state_; }

 private:
  void tick();
  void command(double pitch_rad);
  std::string joint_;
  std::vector<double> pitches_rad_;
  std::size_t next_ = 0;
  State state_ = State::kSweeping;
  std::optional<tinyline_msgs::msg::AlignmentResult> latest_;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::JointState>> command_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::AlignmentResult>> aligned_pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::AlignmentResult>> alignment_sub_;
  std::shared_ptr<bus::Timer> timer_;
};

}  // namespace tinyline::laser_clustering
