// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/nodes/nodes.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include <tinyline/bus/param_table.hpp>
#include <tinyline/msg/eigen.hpp>
#include <tinyline/msg/point_cloud.hpp>

#include "tomato_reasoning/nodes/register.hpp"
#include "tomato_reasoning/nodes/rgbd_folder_camera.hpp"
#include "tomato_reasoning/param_tables.hpp"

namespace tinyline::tomato_reasoning::nodes {

namespace msgs = tinyline_msgs::msg;
using bus::ParamConstraints;
using visualization_msgs::msg::Marker;

namespace {

using tinyline::msg::to_point;
using tinyline::msg::to_pose;

geometry_msgs::msg::Vector3 vec(const Eigen::Vector3d& p) {
  geometry_msgs::msg::Vector3 m;
  m.x = p.x();
  m.y = p.y();
  m.z = p.z();
  return m;
}
Eigen::Vector3d eig(const geometry_msgs::msg::Point& p) { return {p.x, p.y, p.z}; }
Eigen::Vector3d eig(const geometry_msgs::msg::Vector3& p) { return {p.x, p.y, p.z}; }
std_msgs::msg::ColorRGBA colour(float r, float g, float b, float a = 1.0f) {
  std_msgs::msg::ColorRGBA c;
  c.r = r;
  c.g = g;
  c.b = b;
  c.a = a;
  return c;
}
Marker marker(const std_msgs::msg::Header& h, const std::string& ns, int id, int type) {
  Marker m;
  m.header = h;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = Marker::ADD;
  m.pose.orientation.w = 1.0;
  return m;
}
Marker arrow(const std_msgs::msg::Header& h, const std::string& ns, int id, const Eigen::Vector3d& from,
             const Eigen::Vector3d& to, const std_msgs::msg::ColorRGBA& c, double shaft_m) {
  Marker m = marker(h, ns, id, Marker::ARROW);
  m.points = {to_point(from), to_point(to)};
  m.scale.x = shaft_m;
  m.scale.y = 2 * shaft_m;
  m.scale.z = 3 * shaft_m;
  m.color = c;
  return m;
}

}  // namespace

// ---------------------------------------------------------------------------- conversions

std::string to_core(const sensor_msgs::msg::PointCloud2& m, ColorCloud& out) {
  using sensor_msgs::msg::PointField;
  const std::size_t n = std::size_t(m.width) * m.height;
  int ox = -1, oy = -1, oz = -1, orgb = -1;
  for (const auto& f : m.fields) {
    const bool f32 = f.datatype == PointField::FLOAT32, u32 = f.datatype == PointField::UINT32;
    if (f.name == "x" && f32) ox = int(f.offset);
    if (f.name == "y" && f32) oy = int(f.offset);
    if (f.name == "z" && f32) oz = int(f.offset);
    if ((f.name == "rgb" || f.name == "rgba") && (f32 || u32)) orgb = int(f.offset);
  }
  if (ox < 0 || oy < 0 || oz < 0 || orgb < 0) return "PointCloud2 needs float32 fields x, y, z and an rgb field";
  if (m.is_bigendian) return "PointCloud2 is big-endian";
  if (m.point_step < 16 || std::size_t(std::max({ox, oy, oz, orgb})) + 4 > m.point_step)
    return "PointCloud2 point_step " + std::to_string(m.point_step) + " is shorter than its fields";
  if (m.row_step < std::size_t(m.width) * m.point_step || m.data.size() < std::size_t(m.row_step) * m.height)
    return "PointCloud2 holds " + std::to_string(m.data.size()) + " bytes, too few for " + std::to_string(m.width) +
           " x " + std::to_string(m.height) + " points";
  out.width = int(m.width);
  out.height = int(m.height);
  out.xyz.resize(n);
  out.rgb.resize(n);
  for (std::uint32_t r = 0; r < m.height; ++r)
    for (std::uint32_t c = 0; c < m.width; ++c) {
      const std::uint8_t* p = m.data.data() + std::size_t(r) * m.row_step + std::size_t(c) * m.point_step;
      float x, y, z;
      std::uint32_t rgb;
      std::memcpy(&x, p + ox, 4);
      std::memcpy(&y, p + oy, 4);
      std::memcpy(&z, p + oz, 4);
      std::memcpy(&rgb, p + orgb, 4);
      const std::size_t i = std::size_t(r) * m.width + c;
      out.xyz[i] = Eigen::Vector3f(x, y, z);
      out.rgb[i] = Rgb{std::uint8_t(rgb >> 16), std::uint8_t(rgb >> 8), std::uint8_t(rgb)};
    }
  return {};
}

void to_msg(const ColorCloud& c, sensor_msgs::msg::PointCloud2& out) {
  using sensor_msgs::msg::PointField;
  out.height = std::uint32_t(std::max(1, c.height));
  out.width = std::uint32_t(c.size() / out.height);
  msg::set_xyzrgb_fields(out);
  out.is_bigendian = false;
  out.point_step = 16;
  out.row_step = out.point_step * out.width;
  out.data.resize(std::size_t(out.row_step) * out.height);
  bool dense = true;
  for (std::size_t i = 0; i < c.size(); ++i) {
    std::uint8_t* p = out.data.data() + 16 * i;
    std::memcpy(p, c.xyz[i].data(), 12);
    const std::uint32_t rgb = (std::uint32_t(c.rgb[i][0]) << 16) | (std::uint32_t(c.rgb[i][1]) << 8) | c.rgb[i][2];
    std::memcpy(p + 12, &rgb, 4);
    dense = dense && c.finite(i);
  }
  out.is_dense = dense;
}

void to_msg(const PipelineResult& r, const Eigen::Vector3d& gravity, msgs::TomatoEstimates& out) {
  out.tomatoes.clear();
  out.gravity = vec(gravity.normalized());
  out.stage = std::string(to_string(r.stage));
  out.reason = r.status.message;
  out.finite_points = std::uint32_t(r.finite_points);
  out.red_points = std::uint32_t(r.red_points);
  out.hsi_ms = r.times.hsi_ms;
  out.branch_ms = r.times.branch_ms;
  out.smoothing_ms = r.times.smoothing_ms;
  out.spheres_ms = r.times.spheres_ms;
  out.reasoning_ms = r.times.reasoning_ms;
  for (const auto& t : r.tomatoes) {
    msgs::TomatoEstimate e;
    e.centre = to_point(t.fit.sphere.centre);
    e.radius_m = t.fit.sphere.radius_m;
    e.inliers = std::uint32_t(t.fit.inliers.size());
    e.rms_m = t.fit.rms_m;
    e.radius_at_limit = t.fit.radius_at_limit;
    e.pedicel_direction = vec(t.pedicel.expected_dir);
    e.pedicel_spread50_deg = t.pedicel.spread50_deg;
    e.pedicel_spread90_deg = t.pedicel.spread90_deg;
    e.pick_rank = t.pick_rank;
    e.pick_cost = t.cost.cost;
    e.cut_point = to_point(t.cut.point);
    e.cut_direction = vec(t.cut.direction);
    e.cut_coverage = t.cut.coverage;
    e.cut_blocked = t.cut.blocked;
    out.tomatoes.push_back(std::move(e));
  }
  for (const auto& edge : r.edges) {
    out.tomatoes[std::size_t(edge.i)].contacts.push_back(edge.j);
    out.tomatoes[std::size_t(edge.j)].contacts.push_back(edge.i);
  }
  out.pick_order.assign(r.pick_order.begin(), r.pick_order.end());
}

void to_markers(const msgs::TomatoEstimates& t, visualization_msgs::msg::MarkerArray& out) {
  Marker clear;
  clear.header = t.header;
  clear.action = Marker::DELETEALL;
  out.markers.push_back(clear);
  for (std::size_t i = 0; i < t.tomatoes.size(); ++i) {
    const auto& e = t.tomatoes[i];
    const int id = int(i);
    Marker s = marker(t.header, "tomatoes", id, Marker::SPHERE);
    s.pose.position = e.centre;
    s.scale.x = s.scale.y = s.scale.z = 2 * e.radius_m;
    s.color = colour(0.9f, 0.15f, 0.1f, 0.6f);
    out.markers.push_back(s);
    const Eigen::Vector3d c = eig(e.centre), d = eig(e.pedicel_direction);
    out.markers.push_back(arrow(t.header, "pedicels", id, c + e.radius_m * d, c + (e.radius_m + 0.04) * d,
                                colour(0.1f, 0.8f, 0.2f), 0.003));
    out.markers.push_back(arrow(t.header, "cuts", id, c, eig(e.cut_point), colour(0.9f, 0.9f, 0.1f), 0.0015));
    Marker label = marker(t.header, "pick_rank", id, Marker::TEXT_VIEW_FACING);
    label.pose.position = to_point(c - 1.3 * e.radius_m * eig(t.gravity));
    label.scale.z = 0.02;
    label.color = colour(1, 1, 1);
    label.text = "#" + std::to_string(e.pick_rank + 1);
    out.markers.push_back(label);
  }
  Marker edges = marker(t.header, "contacts", 0, Marker::LINE_LIST);
  edges.scale.x = 0.002;
  edges.color = colour(0.2f, 0.5f, 1.0f);
  for (std::size_t i = 0; i < t.tomatoes.size(); ++i)
    for (int j : t.tomatoes[i].contacts)
      if (std::size_t(j) > i) {
        edges.points.push_back(t.tomatoes[i].centre);
        edges.points.push_back(t.tomatoes[std::size_t(j)].centre);
      }
  if (!edges.points.empty()) out.markers.push_back(edges);
}

// ---------------------------------------------------------------------------- tomato_detector

TomatoDetectorNode::TomatoDetectorNode(bus::NodeOptions o) : Node(std::move(o)) {
  PipelineParams p;  // the core's defaults; the table: tomato_reasoning/param_tables.hpp
  bus::declare_params(*this, p);
  if (!(p.gravity.norm() > 0)) throw bus::ParamError({}, "node '" + full_name() + "': gravity must not be all zero");
  p.gravity.normalize();
  require_valid(validate(p).within("tomato pipeline"));
  pipeline_ = std::make_unique<TomatoPipeline>(p);
  views_ =
      declare_parameter("views", 1,
                        "camera views fused per detection: 1 (cloud), or 2 (cloud + cloud2 at cloud2_pose), as the "
                        "thesis's robot (4.5)",
                        ParamConstraints::range(1, 2));
  pub_ = create_publisher<msgs::TomatoEstimates>("tomatoes");
  markers_pub_ = create_publisher<visualization_msgs::msg::MarkerArray>("markers");
  sub_ = create_subscription<sensor_msgs::msg::PointCloud2>(
      "cloud", bus::QoS::keep_last(2), [this](const sensor_msgs::msg::PointCloud2& m) { on_cloud(m); });
  if (views_ == 2) {
    sub2_ = create_subscription<sensor_msgs::msg::PointCloud2>(
        "cloud2", bus::QoS::keep_last(2), [this](const sensor_msgs::msg::PointCloud2& m) { on_cloud2(m); });
    pose2_sub_ = create_subscription<geometry_msgs::msg::PoseStamped>(
        "cloud2_pose", bus::QoS::keep_last(4), [this](const geometry_msgs::msg::PoseStamped& m) { on_cloud2_pose(m); });
  }
}

namespace {
bool same_stamp(const std_msgs::msg::Header& a, const std_msgs::msg::Header& b) {
  return a.stamp.sec == b.stamp.sec && a.stamp.nanosec == b.stamp.nanosec;
}
}  // namespace

void TomatoDetectorNode::on_cloud(const sensor_msgs::msg::PointCloud2& m) {
  header_ = m.header;
  if (auto bad = to_core(m, cloud_); !bad.empty()) {
    // Said at once (whatever the other view brings): this cloud cannot be used.
    auto out = std::make_unique<msgs::TomatoEstimates>();
    out->header = m.header;
    out->stage = "input";
    out->reason = views_ == 2 ? "view 0 (cloud): " + bad : bad;
    out->gravity = vec(pipeline_->params().gravity);
    logger().warn("{}", out->reason);
    header_.reset();
    publish(std::move(out));
    return;
  }
  detect();
}

void TomatoDetectorNode::on_cloud2(const sensor_msgs::msg::PointCloud2& m) {
  header2_ = m.header;
  bad_ = to_core(m, cloud2_);
  if (!bad_.empty()) bad_ = "view 1 (cloud2): " + bad_;
  detect();
}

void TomatoDetectorNode::on_cloud2_pose(const geometry_msgs::msg::PoseStamped& m) {
  const auto& q = m.pose.orientation;
  const Eigen::Quaterniond rot(q.w, q.x, q.y, q.z);
  const Eigen::Vector3d t(m.pose.position.x, m.pose.position.y, m.pose.position.z);
  pose2_header_ = m.header;
  if (!rot.coeffs().allFinite() || !t.allFinite() || std::abs(rot.norm() - 1.0) > 1e-3) {
    // Not normalised silently: a bad quaternion means a broken pose source.
    T_ref_camera2_.matrix().setConstant(std::numeric_limits<double>::quiet_NaN());
  } else {
    T_ref_camera2_ = tinyline::msg::to_isometry(m.pose);
  }
  detect();
}

void TomatoDetectorNode::detect() {
  if (!header_) return;
  auto out = std::make_unique<msgs::TomatoEstimates>();
  out->header = *header_;
  if (views_ == 1) {
    const PipelineResult r = pipeline_->run(cloud_);
    to_msg(r, pipeline_->params().gravity, *out);
    if (!r.status.ok()) logger().info("no tomatoes ({}): {}", to_string(r.stage), r.status.message);
  } else {
    // One detection per stamp: wait for the other view and its pose.
    if (!header2_ || !pose2_header_ || !same_stamp(*header_, *header2_) || !same_stamp(*header_, *pose2_header_))
      return;
    if (!bad_.empty()) {
      out->stage = "input";
      out->reason = bad_;
      out->gravity = vec(pipeline_->params().gravity);
      logger().warn("{}", bad_);
    } else if (!T_ref_camera2_.matrix().allFinite()) {
      out->stage = "input";
      out->reason = "cloud2_pose is not a finite pose with a unit quaternion";
      out->gravity = vec(pipeline_->params().gravity);
      logger().warn("{}", out->reason);
    } else {
      View v0, v1;
      v0.cloud = cloud_;
      v1.cloud = cloud2_;
      v1.T_ref_camera = T_ref_camera2_;
      const PipelineResult r = pipeline_->run(std::vector<View>{v0, v1});
      to_msg(r, pipeline_->params().gravity, *out);
      if (!r.status.ok()) logger().info("no tomatoes ({}): {}", to_string(r.stage), r.status.message);
    }
  }
  header_.reset();
  header2_.reset();
  pose2_header_.reset();
  publish(std::move(out));
}

void TomatoDetectorNode::publish(std::unique_ptr<msgs::TomatoEstimates> out) {
  if (!out->tomatoes.empty()) {
    std::string order;
    for (int i : out->pick_order) order += (order.empty() ? "" : " ") + std::to_string(i);
    logger().info("{} tomatoes, pick order [{}] ({:.1f} ms)", out->tomatoes.size(), order,
                  out->hsi_ms + out->branch_ms + out->smoothing_ms + out->spheres_ms + out->reasoning_ms);
  }
  if (markers_pub_->subscription_count() > 0) {
    auto mk = std::make_unique<visualization_msgs::msg::MarkerArray>();
    to_markers(*out, *mk);
    markers_pub_->publish(std::move(mk));
  }
  pub_->publish(std::move(out));
}

// ---------------------------------------------------------------------------- pick_verifier

PickVerifierNode::PickVerifierNode(bus::NodeOptions o) : Node(std::move(o)) {
  bus::declare_params(*this, params_);  // the tables: tomato_reasoning/param_tables.hpp
  bus::declare_params(*this, harvest_);
  require_valid(validate(harvest_).within("harvest"));
  max_picks_ = declare_parameter("max_picks", 0, "verify at most this many picks (0: every tomato)",
                                 ParamConstraints::range(0, 1000));
  pose_pub_ = create_publisher<geometry_msgs::msg::PoseStamped>("pick_pose");
  expected_pub_ = create_publisher<geometry_msgs::msg::PointStamped>("expected_pedicel");
  result_pub_ = create_publisher<msgs::PickVerification>("verification", bus::QoS::keep_last(64));
  cut_pub_ = create_publisher<msgs::CutCommand>("cut", bus::QoS::keep_last(8));
  summary_pub_ = create_publisher<msgs::HarvestSummary>("summary", bus::QoS::keep_last(4));
  markers_pub_ = create_publisher<visualization_msgs::msg::MarkerArray>("markers");
  tomatoes_sub_ = create_subscription<msgs::TomatoEstimates>(
      "tomatoes", bus::QoS::keep_last(2), [this](const msgs::TomatoEstimates& m) { on_tomatoes(m); });
  pedicel_sub_ = create_subscription<msgs::PedicelDetection>(
      "pedicel", bus::QoS::keep_last(5), [this](const msgs::PedicelDetection& m) { on_pedicel(m); });
  cut_sub_ = create_subscription<msgs::CutOutcome>("cut_outcome", bus::QoS::keep_last(8),
                                                   [this](const msgs::CutOutcome& m) { on_cut_outcome(m); });
}

void PickVerifierNode::on_tomatoes(const msgs::TomatoEstimates& m) {
  if (estimates_) return;  // one harvest per run: the first estimate with tomatoes
  if (m.tomatoes.empty()) {
    logger().info("no tomatoes to pick yet ({}: {})", m.stage, m.reason);
    return;
  }
  estimates_ = m;
  rank_ = 0;
  std::string order;
  for (int k : m.pick_order) order += (order.empty() ? "" : " ") + std::to_string(k);
  logger().info("{} tomatoes found; pick order [{}]", m.tomatoes.size(), order);
  for (int k : m.pick_order) {
    const auto& e = m.tomatoes[std::size_t(k)];
    logger().info(
        "  tomato {}: centre ({:.3f}, {:.3f}, {:.3f}) m, r {:.1f} mm, {} contacts, pedicel ({:+.2f}, {:+.2f}, {:+.2f}) "
        "+-{:.0f} deg, cut at ({:.3f}, {:.3f}, {:.3f}) covering {:.0f}%",
        k, e.centre.x, e.centre.y, e.centre.z, 1000 * e.radius_m, e.contacts.size(), e.pedicel_direction.x,
        e.pedicel_direction.y, e.pedicel_direction.z, e.pedicel_spread50_deg, e.cut_point.x, e.cut_point.y,
        e.cut_point.z, 100 * e.cut_coverage);
  }
  next_pick();
}

void PickVerifierNode::next_pick() {
  const auto& m = *estimates_;
  const std::size_t n =
      max_picks_ > 0 ? std::min<std::size_t>(std::size_t(max_picks_), m.pick_order.size()) : m.pick_order.size();
  if (rank_ >= n) {
    summary();
    return;
  }
  const int k = m.pick_order[rank_];
  const auto& e = m.tomatoes[std::size_t(k)];
  auto sphere = [](const auto& o) {
    Sphere s;
    s.centre = eig(o.centre);
    s.radius_m = o.radius_m;
    return s;
  };
  // The fruit still hanging (those earlier in the order are gone) stay out of the blades and the laser's view.
  std::vector<Sphere> others;
  for (std::size_t j = 0; j < m.tomatoes.size(); ++j)
    if (static_cast<int>(j) != k && std::find(m.pick_order.begin(), m.pick_order.begin() + long(rank_), int(j)) ==
                                        m.pick_order.begin() + long(rank_))
      others.push_back(sphere(m.tomatoes[j]));
  const std::vector<CutCandidate> cuts = cut_candidates(sphere(e), eig(e.cut_direction), others, params_);
  PickPose pose = cuts.empty() ? picking_pose(eig(e.cut_point), eig(e.cut_direction), params_) : cuts.front().pose;
  pose.tomato = pose.ok() ? k : -1;
  attempts_.emplace(pose, harvest_);
  if (!pose.ok() || (!cuts.empty() && !cuts.front().fits(params_))) {
    Verification v;
    v.outcome = Verification::Outcome::kFailed;
    v.reason = pose.ok() ? "no cut clears the blades (the nearest fruit " +
                               std::to_string(std::lround(1000 * cuts.front().blade_clear_m)) + " mm from them)"
                         : "no picking pose: " + pose.reason;
    publish_verification(v);
    return end_pick(PickOutcome::kLeftForHuman, "1: " + v.reason);
  }
  scan();
}

void PickVerifierNode::scan() {
  // The finder's prior: the pedicel at the blade throat (laser frame).
  auto expected = std::make_unique<geometry_msgs::msg::PointStamped>();
  expected->header.stamp = now().to_msg();
  expected->header.frame_id = "hand_laser";
  expected->point.z = params_.throat_z_m;
  expected_pub_->publish(std::move(expected));
  auto p = std::make_unique<geometry_msgs::msg::PoseStamped>();
  p->header.stamp = now().to_msg();
  p->header.frame_id = estimates_->header.frame_id;
  p->pose = to_pose(attempts_->pose().T_ref_laser);
  waiting_ = Waiting::kScan;
  pose_pub_->publish(std::move(p));
}

void PickVerifierNode::on_pedicel(const msgs::PedicelDetection& d) {
  if (waiting_ != Waiting::kScan || !estimates_) return;
  waiting_ = Waiting::kNothing;
  FinderAnswer a;
  switch (d.outcome) {
    case msgs::PedicelDetection::CUT_HERE: a.outcome = FinderAnswer::Outcome::kCutHere; break;
    case msgs::PedicelDetection::MOVE: a.outcome = FinderAnswer::Outcome::kMove; break;
    case msgs::PedicelDetection::NOTHING_TO_CUT: a.outcome = FinderAnswer::Outcome::kNothingToCut; break;
    case msgs::PedicelDetection::OUT_OF_VIEW: a.outcome = FinderAnswer::Outcome::kOutOfView; break;
    default: a.outcome = FinderAnswer::Outcome::kInvalidInput; break;
  }
  a.lateral_offset_m = d.lateral_offset_m;
  a.depth_offset_m = d.depth_offset_m;
  a.pedicel_x_m = d.position.x;
  a.pedicel_z_m = d.position.z;
  a.confidence = d.confidence;
  a.reason = d.reason;
  const Verification v = verify(attempts_->pose(), a, params_);
  publish_verification(v);
  act(attempts_->after_verification(v));
}

void PickVerifierNode::publish_verification(const Verification& v) {
  const PickPose& pose = attempts_->pose();
  msgs::PickVerification out;
  out.header.stamp = now().to_msg();
  out.header.frame_id = estimates_->header.frame_id;
  out.tomato = estimates_->pick_order[rank_];
  out.pick_rank = int(rank_);
  out.attempt = std::uint8_t(attempts_->attempt());
  out.laser_pose = to_pose(pose.T_ref_laser);
  out.planned_cut = to_point(pose.cut_point);
  out.outcome = std::uint8_t(v.outcome);
  static_assert(int(Verification::Outcome::kCutHere) == msgs::PickVerification::CUT_HERE);
  static_assert(int(Verification::Outcome::kFailed) == msgs::PickVerification::FAILED);
  out.reason = v.reason;
  out.move = vec(v.move);
  out.cut_point = to_point(v.cut_point);
  out.confidence = v.confidence;
  logger().info("pick {} (tomato {}), attempt {}: {}{} ({})", rank_ + 1, out.tomato, out.attempt, to_string(v.outcome),
                v.outcome == Verification::Outcome::kMove
                    ? " by " + std::to_string(int(std::lround(1000 * v.move.norm()))) + " mm"
                    : "",
                v.reason);
  if (markers_pub_->subscription_count() > 0 && pose.ok()) {
    auto mk = std::make_unique<visualization_msgs::msg::MarkerArray>();
    std_msgs::msg::Header h = out.header;
    const int id = int(2 * rank_) + out.attempt - 1;
    const Eigen::Vector3d o = pose.T_ref_laser.translation();
    mk->markers.push_back(arrow(h, "hand_laser", id, o, pose.cut_point, colour(0.2f, 0.9f, 0.9f), 0.002));
    if (v.will_cut())
      mk->markers.push_back(arrow(h, "verified_cut", id, pose.cut_point, v.cut_point, colour(1, 0.4f, 1), 0.002));
    markers_pub_->publish(std::move(mk));
  }
  results_.push_back(out);
  result_pub_->publish(std::make_unique<msgs::PickVerification>(out));
}

void PickVerifierNode::act(const GripperStep& step) {
  switch (step.action) {
    case GripperStep::Action::kRescan: return scan();
    case GripperStep::Action::kDone: return end_pick(step.outcome, attempts_->detail());
    case GripperStep::Action::kCut: break;
  }
  const int k = estimates_->pick_order[rank_];
  const auto& e = estimates_->tomatoes[std::size_t(k)];
  auto c = std::make_unique<msgs::CutCommand>();
  c->header.stamp = now().to_msg();
  c->header.frame_id = estimates_->header.frame_id;
  c->tomato = k;
  c->pick_rank = int(rank_);
  c->attempt = std::uint8_t(attempts_->attempt());
  c->laser_pose = to_pose(step.T_ref_laser);
  c->throat_z_m = params_.throat_z_m;
  c->target_centre = e.centre;
  c->target_radius_m = e.radius_m;
  waiting_ = Waiting::kCut;
  cut_pub_->publish(std::move(c));
}

void PickVerifierNode::on_cut_outcome(const msgs::CutOutcome& m) {
  if (waiting_ != Waiting::kCut || !estimates_ || m.pick_rank != int(rank_)) return;
  waiting_ = Waiting::kNothing;
  BladeResult r = BladeResult::kJammed;
  switch (m.result) {
    case msgs::CutOutcome::CUT_TARGET: r = BladeResult::kCutTarget; break;
    case msgs::CutOutcome::CUT_OTHER_PEDICEL: r = BladeResult::kCutOtherPedicel; break;
    case msgs::CutOutcome::CLOSED_ON_NOTHING: r = BladeResult::kClosedOnNothing; break;
    default: r = BladeResult::kJammed; break;
  }
  logger().info("pick {} (tomato {}), attempt {}: the blades closed: {}{}", rank_ + 1, m.tomato, m.attempt,
                to_string(r), m.object.empty() ? "" : " on " + m.object);
  act(attempts_->after_cut(r));
}

void PickVerifierNode::end_pick(PickOutcome outcome, const std::string& detail) {
  const int k = estimates_->pick_order[rank_];
  const auto& e = estimates_->tomatoes[std::size_t(k)];
  msgs::HarvestPick p;
  p.tomato = k;
  p.pick_rank = int(rank_);
  p.centre = e.centre;
  p.radius_m = e.radius_m;
  p.attempts = std::uint8_t(attempts_->attempt());
  p.outcome = std::uint8_t(outcome);
  static_assert(int(PickOutcome::kPicked) == msgs::HarvestPick::PICKED);
  static_assert(int(PickOutcome::kLeftForHuman) == msgs::HarvestPick::LEFT_FOR_HUMAN);
  p.detail = detail;
  picks_.push_back(p);
  attempts_.reset();
  ++rank_;
  next_pick();
}

void PickVerifierNode::summary() {
  if (done_) return;
  done_ = true;
  int by_outcome[4] = {0, 0, 0, 0}, second = 0;
  logger().info("harvest: {} tomatoes, pick by pick:", estimates_->tomatoes.size());
  for (const auto& p : picks_) {
    by_outcome[p.outcome] += 1;
    second += p.outcome == msgs::HarvestPick::PICKED && p.attempts == 2;
    logger().info("  pick {}: tomato {}, {} attempt(s): {} ({})", p.pick_rank + 1, p.tomato, p.attempts,
                  to_string(PickOutcome(p.outcome)), p.detail);
  }
  logger().info(
      "harvest summary: {} tomatoes, {} picks: {} picked ({} at the second attempt), {} cut failures, "
      "{} cut another's pedicel, {} left for a human",
      estimates_->tomatoes.size(), picks_.size(), by_outcome[0], second, by_outcome[1], by_outcome[2], by_outcome[3]);
  auto out = std::make_unique<msgs::HarvestSummary>();
  out->header.stamp = now().to_msg();
  out->header.frame_id = estimates_->header.frame_id;
  out->detected = std::uint32_t(estimates_->tomatoes.size());
  out->picks = picks_;
  summary_pub_->publish(std::move(out));
}

}  // namespace tinyline::tomato_reasoning::nodes

namespace tinyline::tomato_reasoning {

void register_nodes(bus::NodeRegistry& r) {
  r.add<nodes::TomatoDetectorNode>(
      "tomato_reasoning", "tomato_detector",
      "RGB-D cloud -> tomato spheres, pedicel estimates, pick order, cut plans (thesis 4.3)");
  r.add<nodes::PickVerifierNode>(
      "tomato_reasoning", "pick_verifier",
      "the harvest in pick order: picking poses, the hand laser's pedicel finding -> cut here / move / nothing (4.4), "
      "re-scans, closing the scissors; a summary when every tomato had its pick");
  r.add<nodes::RgbdFolderCameraNode>(
      "tomato_reasoning", "rgbd_folder_camera",
      "a folder of RGB-D frames (colour + 16-bit depth PNG + intrinsics) played as a camera: cloud");
}

}  // namespace tinyline::tomato_reasoning
