// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/nodes/circle_fitter_node.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include <tinyline/bus/param_table.hpp>

#include "hydrus_fitting/param_tables.hpp"
#include "hydrus_fitting/sequencer.hpp"

namespace tinyline::hydrus_fitting {

using bus::ParamConstraints;
namespace msgs = tinyline_msgs::msg;
namespace vis = visualization_msgs::msg;

namespace {

constexpr std::size_t kScanQueue = 8;

// The fit statuses go on the wire as their enum values.
constexpr std::uint8_t wire(FitStatus s) { return static_cast<std::uint8_t>(s); }
static_assert(wire(FitStatus::kOk) == msgs::CircleFit::STATUS_OK);
static_assert(wire(FitStatus::kTooFewPoints) == msgs::CircleFit::STATUS_TOO_FEW_POINTS);
static_assert(wire(FitStatus::kCollinear) == msgs::CircleFit::STATUS_COLLINEAR);
static_assert(wire(FitStatus::kNoConsensus) == msgs::CircleFit::STATUS_NO_CONSENSUS);
static_assert(wire(FitStatus::kRadiusOutOfRange) == msgs::CircleFit::STATUS_RADIUS_OUT_OF_RANGE);
static_assert(wire(FitStatus::kInvalidParams) == msgs::CircleFit::STATUS_INVALID_PARAMS);

std_msgs::msg::ColorRGBA colour(float r, float g, float b, float a) {
  std_msgs::msg::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}

geometry_msgs::msg::Point point(double x, double y, double z) {
  geometry_msgs::msg::Point p;
  p.x = x;
  p.y = y;
  p.z = z;
  return p;
}

}  // namespace

CircleFitterNode::CircleFitterNode(bus::NodeOptions o) : Node(std::move(o)) {
  ParamConstraints required;
  required.required = true;
  description_path_ = declare_parameter<std::string>("robot_description", "",
                                                     "robot description YAML (links, joints, sensor mounts)", required);
  frame_id_ = declare_parameter<std::string>("frame_id", "base", "frame of the outputs: the robot description's base");
  bus::declare_params(*this, params_);  // the tables: hydrus_fitting/param_tables.hpp
  JointBufferParams joints;
  bus::declare_params(*this, joints, "joint_");
  joint_tolerance_s_ = joints.tolerance_s;
  joint_history_s_ = joints.history_s;
  BasePoseBufferParams base_poses;
  bus::declare_params(*this, base_poses, "base_pose_");
  base_pose_tolerance_s_ = base_poses.tolerance_s;
  base_pose_history_s_ = base_poses.history_s;
  marker_height_m_ = declare_parameter("marker_height_m", 0.3, "height of the cylinder marker [m]",
                                       ParamConstraints::range(0.0, 10.0));
  publish_points_ = declare_parameter("publish_points", true, "add the fused points and the links to the markers");
  require_valid(validate(params_.robust));
  require_valid(validate(params_.fusion));
  require_valid(validate(joints));
  require_valid(validate(base_poses));

  circle_pub_ = create_publisher<msgs::CircleFit>("circle");
  marker_pub_ = create_publisher<vis::MarkerArray>("markers");
  scan_sub_ = create_subscription<msgs::LineScan>("scans", bus::QoS::keep_last(kScanQueue),
                                                  [this](const msgs::LineScan& m) { on_scan(m); });
  joint_sub_ = create_subscription<sensor_msgs::msg::JointState>(
      "joint_states", bus::QoS::keep_last(50), [this](const sensor_msgs::msg::JointState& m) { on_joints(m); });
  base_pose_sub_ = create_subscription<geometry_msgs::msg::PoseStamped>(
      "base_pose", bus::QoS::keep_last(50), [this](const geometry_msgs::msg::PoseStamped& m) { on_base_pose(m); });
}

void CircleFitterNode::on_start() {
  // Throws RobotModelError naming file, line and field: the launch stops there.
  model_ = std::make_unique<RobotModel>(RobotModel::load(description_path_));
  joints_ = std::make_unique<JointStateBuffer>(model_->joint_names(),
                                               JointBufferParams{joint_tolerance_s_, joint_history_s_});
  base_poses_ = std::make_unique<BasePoseBuffer>(BasePoseBufferParams{base_pose_tolerance_s_, base_pose_history_s_});
  estimator_ = std::make_unique<CircleEstimator>(*model_, params_);
  latest_.assign(model_->sensors().size(), std::nullopt);
  logger().info("robot '{}': {} links, {} sensors ({})", model_->name(), model_->links().size(),
                model_->sensors().size(), description_path_);
}

void CircleFitterNode::on_joints(const sensor_msgs::msg::JointState& m) {
  if (!joints_) return;
  const auto r = joints_->add(bus::Time::from_msg(m.header.stamp).ns, m.name, m.position);
  if (!r.reason.empty() && r.reason != last_joint_warning_) {
    logger().warn("joint_states: {}", r.reason);  // once per distinct problem
    last_joint_warning_ = r.reason;
  }
}

void CircleFitterNode::on_base_pose(const geometry_msgs::msg::PoseStamped& m) {
  if (!base_poses_) return;
  // Yaw of the quaternion about the fixed frame's z (the sensing plane is level).
  const auto& o = m.pose.orientation;
  const double yaw = std::atan2(2.0 * (o.w * o.z + o.x * o.y), 1.0 - 2.0 * (o.y * o.y + o.z * o.z));
  if (!base_poses_->add(bus::Time::from_msg(m.header.stamp).ns, {m.pose.position.x, m.pose.position.y}, yaw) &&
      last_base_warning_ != "non-finite") {
    logger().warn("base_pose: a pose with a non-finite position or orientation was ignored");
    last_base_warning_ = "non-finite";
  }
}

void CircleFitterNode::on_scan(const msgs::LineScan& m) {
  if (!model_) return;
  const auto sensor = model_->sensor_index(m.header.frame_id);
  if (!sensor) {
    if (unknown_[m.header.frame_id]++ == 0) {
      std::string known;
      for (const auto& s : model_->sensors()) known += (known.empty() ? "" : ", ") + s.name;
      logger().error(
          "scan from sensor '{}' (header.frame_id) is not in the robot description '{}' ({}); its scans "
          "are ignored. Sensors there: {}",
          m.header.frame_id, model_->name(), description_path_, known);
    }
    return;
  }
  auto& slot = latest_[static_cast<std::size_t>(*sensor)];
  if (!slot) slot.emplace();
  slot->stamp_ns = bus::Time::from_msg(m.header.stamp).ns;
  const std::size_t n = std::min(m.angles.size(), m.distance_m.size());
  slot->angle.resize(n);
  slot->range.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const bool valid = m.status.size() != m.distance_m.size() || m.status[i] == msgs::LineScan::STATUS_VALID;
    slot->angle[i] = m.angles[i];
    slot->range[i] = valid ? static_cast<double>(m.distance_m[i]) : std::numeric_limits<double>::quiet_NaN();
  }
  if (m.angles.size() != m.distance_m.size()) {
    logger().warn("scan from '{}' has {} angles and {} distances: used the first {}", m.header.frame_id,
                  m.angles.size(), m.distance_m.size(), n);
  }

  std::vector<ScanView> views;
  views.reserve(latest_.size());
  for (std::size_t s = 0; s < latest_.size(); ++s) {
    if (!latest_[s]) continue;
    views.push_back({model_->sensors()[s].name, latest_[s]->stamp_ns, latest_[s]->angle, latest_[s]->range});
  }
  const CircleEstimate e = estimator_->estimate(views, *joints_, base_poses_->empty() ? nullptr : base_poses_.get());
  if (!e.base_motion_reason.empty() && e.base_motion_reason != last_base_warning_) {
    logger().warn("base_pose: {}", e.base_motion_reason);  // once per distinct problem
    last_base_warning_ = e.base_motion_reason;
  }
  publish(e);
}

void CircleFitterNode::publish(const CircleEstimate& e) {
  auto out = std::make_unique<msgs::CircleFit>();
  out->header.stamp = bus::Time::from_ns(e.stamp_ns).to_msg();
  out->header.frame_id = frame_id_;
  out->status = wire(e.fit.detail);
  out->reason = e.fit.status.message;
  if (out->reason.empty() && e.fit.ok()) {
    // Say which scans were left out, if any: the fit is fine but partial.
    for (const auto& s : e.scans)
      if (!s.ok()) out->reason += (out->reason.empty() ? "" : "; ") + s.status.message;
  }
  const double z = model_->sensor_height_m();
  out->centre = point(e.fit.circle.centre_m.x(), e.fit.circle.centre_m.y(), z);
  out->radius_m = e.fit.circle.radius_m;
  out->radius_known = params_.robust.known_radius_m.has_value();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out->covariance[static_cast<std::size_t>(3 * r + c)] = e.fit.covariance(r, c);
  out->rms_residual_m = e.fit.rms_residual_m;
  out->inliers = static_cast<std::uint32_t>(e.fit.ok() ? e.fit.points_used : 0);
  out->points = static_cast<std::uint32_t>(e.points);
  out->self_filtered = static_cast<std::uint32_t>(e.self_filtered);
  out->scans = static_cast<std::uint32_t>(e.scans_fused);
  out->hypotheses = static_cast<std::uint32_t>(e.fit.iterations);
  const auto stamp = out->header.stamp;
  circle_pub_->publish(std::move(out));

  if (marker_pub_->subscription_count() == 0) return;
  auto arr = std::make_unique<vis::MarkerArray>();
  vis::Marker cyl;
  cyl.header.stamp = stamp;
  cyl.header.frame_id = frame_id_;
  cyl.ns = "circle";
  cyl.id = 0;
  cyl.type = vis::Marker::CYLINDER;
  cyl.action = e.fit.ok() ? vis::Marker::ADD : vis::Marker::DELETE;
  cyl.pose.position = point(e.fit.circle.centre_m.x(), e.fit.circle.centre_m.y(), z);
  cyl.pose.orientation.w = 1.0;
  cyl.scale.x = cyl.scale.y = 2.0 * e.fit.circle.radius_m;
  cyl.scale.z = marker_height_m_;
  cyl.color = colour(0.1f, 0.8f, 0.2f, 0.5f);
  arr->markers.push_back(std::move(cyl));
  if (publish_points_) {
    const FusedCloud& c = estimator_->cloud();
    vis::Marker pts;
    pts.header.stamp = stamp;
    pts.header.frame_id = frame_id_;
    pts.ns = "points";
    pts.id = 1;
    pts.type = vis::Marker::POINTS;
    pts.action = vis::Marker::ADD;
    pts.pose.orientation.w = 1.0;
    pts.scale.x = pts.scale.y = 0.006;
    const auto P = c.points_m();
    for (int i = 0; i < c.size(); ++i) {
      pts.points.push_back(point(P(0, i), P(1, i), z));
      const bool in = e.fit.ok() && e.fit.inlier_mask[static_cast<std::size_t>(i)];
      pts.colors.push_back(in ? colour(0.1f, 0.9f, 0.2f, 1.0f) : colour(0.9f, 0.2f, 0.1f, 1.0f));
    }
    arr->markers.push_back(std::move(pts));
    const JointLookup q = joints_->at(e.stamp_ns);
    if (q.ok()) {
      vis::Marker links;
      links.header.stamp = stamp;
      links.header.frame_id = frame_id_;
      links.ns = "links";
      links.id = 2;
      links.type = vis::Marker::LINE_LIST;
      links.action = vis::Marker::ADD;
      links.pose.orientation.w = 1.0;
      links.scale.x = 0.02;
      links.color = colour(0.2f, 0.4f, 0.9f, 1.0f);
      for (const auto& cap : link_capsules(*model_, model_->forward(q.positions))) {
        links.points.push_back(point(cap.a_m.x(), cap.a_m.y(), z));
        links.points.push_back(point(cap.b_m.x(), cap.b_m.y(), z));
      }
      arr->markers.push_back(std::move(links));
    }
  }
  marker_pub_->publish(std::move(arr));
}

}  // namespace tinyline::hydrus_fitting
