// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/nodes/nodes.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <vector>

#include <fmt/format.h>

#include <tinyline/bus/param_table.hpp>

#include "common.hpp"
#include "laser_clustering/param_tables.hpp"
#include "laser_clustering/nodes/conversions.hpp"
#include "laser_clustering/nodes/register.hpp"

namespace tinyline::laser_clustering {

using bus::ParamConstraints;
// The core has types of the same names (LineScan, PedicelDetection,
// AlignmentResult): messages are always spelled msgs::.
namespace msgs = tinyline_msgs::msg;

namespace {
constexpr std::size_t kScanQueue = 5;

// The outcomes go on the wire as their enum values.
constexpr std::uint8_t wire(AlignmentOutcome o) { return static_cast<std::uint8_t>(o); }
static_assert(wire(AlignmentOutcome::kFound) == msgs::AlignmentResult::FOUND);
static_assert(wire(AlignmentOutcome::kAtSweepEdge) == msgs::AlignmentResult::AT_SWEEP_EDGE);
static_assert(wire(AlignmentOutcome::kNoPeak) == msgs::AlignmentResult::NO_PEAK);
static_assert(wire(AlignmentOutcome::kInvalidInput) == msgs::AlignmentResult::INVALID_INPUT);
}  // namespace

// ---------------------------------------------------------------------------- line_clusterer

detail::ScanToClusters::ScanToClusters(bus::Node& node, Cluster cluster)
    : node_(node), cluster_(std::move(cluster)), min_reflectance_(nodes::declare_min_reflectance(node)) {
  pub_ = node.create_publisher<msgs::LineClusters>("clusters");
  sub_ = node.create_subscription<msgs::LineScan>("scan", bus::QoS::keep_last(kScanQueue),
                                                  [this](const msgs::LineScan& m) { on_scan(m); });
}

void detail::ScanToClusters::on_scan(const msgs::LineScan& m) {
  auto out = std::make_unique<msgs::LineClusters>();
  out->header = m.header;
  if (const auto bad = nodes::to_core(m, scan_, min_reflectance_); !bad.empty()) {
    node_.logger().warn("{}", bad);
    out->brightest = -1;
    out->note = bad;
  } else {
    cluster_(scan_, *out);
  }
  pub_->publish(std::move(out));
}

LineClustererNode::LineClustererNode(bus::NodeOptions o)
    : Node(std::move(o)),
      clusterer_(bus::declared_settings<TwoStageParams>(*this)),
      topics_(*this, [this](const LineScan& scan, msgs::LineClusters& out) {
        clusterer_.run(scan, objects_);
        nodes::to_msg(objects_, out);
      }) {}

// ---------------------------------------------------------------------------- pedicel_finder

PedicelFinderNode::PedicelFinderNode(bus::NodeOptions o)
    : Node(std::move(o)),
      clusterer_(bus::declared_settings<TwoStageParams>(*this)),
      finder_(bus::declared_settings<PedicelFinderParams>(*this)) {
  min_reflectance_ = nodes::declare_min_reflectance(*this);
  expectation_sd_m_ =
      declare_parameter("expectation_sd_m", 0.015, "how far off the vision's expected pedicel may be [m]",
                        ParamConstraints::range(1e-4, 1.0));
  expectation_max_age_s_ = declare_parameter("expectation_max_age_s", 1.0,
                                             "an expected_pedicel older than this (vs the scan) is ignored [s]",
                                             ParamConstraints::range(0.0, 3600.0));
  pub_ = create_publisher<msgs::PedicelDetection>("pedicel");
  clusters_pub_ = create_publisher<msgs::LineClusters>("clusters");
  sub_ = create_subscription<msgs::LineScan>("scan", bus::QoS::keep_last(kScanQueue),
                                             [this](const msgs::LineScan& m) { on_scan(m); });
  // The laser plane is x-z: the points' y (off the plane) is not used.
  expected_sub_ = create_subscription<geometry_msgs::msg::PointStamped>(
      "expected_pedicel", bus::QoS::keep_last(1), [this](const geometry_msgs::msg::PointStamped& p) {
        expected_ =
            std::make_pair(bus::Time::from_msg(p.header.stamp),
                           PedicelExpectation{Eigen::Vector2d(p.point.x, p.point.z), expectation_sd_m_, {}, 0.015});
      });
  layout_sub_ = create_subscription<msgs::PedicelLayout>(
      "expected_layout", bus::QoS::keep_last(1), [this](const msgs::PedicelLayout& l) {
        // A malformed layout is dropped whole, with the reason: half a
        // layout would blame the wrong candidates.
        PedicelExpectation e;
        if (const auto bad = from_msg(l, expectation_sd_m_, e); !bad.empty()) {
          logger().warn("expected_layout (stamp {:.3f} s, frame '{}') ignored: {}",
                        bus::Time::from_msg(l.header.stamp).seconds(), l.header.frame_id, bad);
          return;
        }
        expected_ = std::make_pair(bus::Time::from_msg(l.header.stamp), std::move(e));
      });
}

void PedicelFinderNode::on_scan(const msgs::LineScan& m) {
  auto det = std::make_unique<msgs::PedicelDetection>();
  det->header = m.header;
  det->cluster = -1;
  if (const auto bad = nodes::to_core(m, scan_, min_reflectance_); !bad.empty()) {
    logger().warn("{}", bad);
    det->outcome = msgs::PedicelDetection::INVALID_INPUT;
    det->reason = bad;
    pub_->publish(std::move(det));
    return;
  }
  clusterer_.run(scan_, objects_);
  const TwoStageResult& objects = objects_;
  std::optional<PedicelExpectation> expectation;
  const bus::Time stamp = bus::Time::from_msg(m.header.stamp);
  if (expected_ && std::abs(bus::to_seconds(stamp - expected_->first)) <= expectation_max_age_s_) {
    expectation = expected_->second;
  }
  to_msg(find_pedicel(scan_, objects, finder_, expectation), *det);
  pub_->publish(std::move(det));
  if (clusters_pub_->subscription_count() > 0) {
    auto c = std::make_unique<msgs::LineClusters>();
    c->header = m.header;
    nodes::to_msg(objects, *c);
    clusters_pub_->publish(std::move(c));
  }
}

// ---------------------------------------------------------------------------- tomato_registration

TomatoRegistrationNode::TomatoRegistrationNode(bus::NodeOptions o)
    : Node(std::move(o)), params_(bus::declared_settings<TomatoRegistrationParams>(*this)) {
  min_reflectance_ = nodes::declare_min_reflectance(*this);
  expectation_max_age_s_ = declare_parameter("expectation_max_age_s", 1.0,
                                             "expected tomatoes further than this from a scan's stamp are stale: the "
                                             "gripper may have moved since [s]",
                                             ParamConstraints::range(0.0, 3600.0));
  pub_ = create_publisher<msgs::TrussRegistration>("truss_registration");
  tomatoes_sub_ = create_subscription<msgs::ExpectedTomatoes>(
      "expected_tomatoes", bus::QoS::keep_last(1), [this](const msgs::ExpectedTomatoes& m) { on_tomatoes(m); });
  sub_ = create_subscription<msgs::LineScan>("scan", bus::QoS::keep_last(kScanQueue),
                                             [this](const msgs::LineScan& m) { on_scan(m); });
}

void TomatoRegistrationNode::on_tomatoes(const msgs::ExpectedTomatoes& m) {
  // The newest message replaces the last even when malformed: the old
  // tomatoes belong to an older look, and registering a new scan on them
  // would answer a question nobody asked. The malformed one answers each
  // scan with why.
  Expected e{bus::Time::from_msg(m.header.stamp), m.header.frame_id, {}, m.max_shift_m, {}};
  if (m.radii_m.size() != m.centres.size()) {
    e.malformed = fmt::format("{} centres but {} radii_m", m.centres.size(), m.radii_m.size());
  } else if (!(std::isfinite(m.max_shift_m) && m.max_shift_m >= 0.0)) {
    e.malformed = fmt::format("max_shift_m must be finite and >= 0 (0: the node's), got {}", m.max_shift_m);
  }
  for (std::size_t i = 0; e.malformed.empty() && i < m.centres.size(); ++i) {
    const auto& c = m.centres[i];
    const double r = m.radii_m[i];
    if (!(std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z))) {
      e.malformed = fmt::format("tomato {} has a non-finite centre ({}, {}, {})", i, c.x, c.y, c.z);
    } else if (!(std::isfinite(r) && r > 0.0)) {
      e.malformed = fmt::format("tomato {} has radius {}; it must be finite and > 0", i, r);
    } else {
      e.tomatoes.push_back({Eigen::Vector3d(c.x, c.y, c.z), r});
    }
  }
  if (!e.malformed.empty()) {
    e.tomatoes.clear();
    logger().warn(
        "expected_tomatoes (stamp {:.3f} s, frame '{}') malformed; scans of that frame get ok = false "
        "with why: {}",
        e.stamp.seconds(), e.frame_id, e.malformed);
  }
  expected_ = std::move(e);
}

void TomatoRegistrationNode::skip(Miss miss, const std::string& why) {
  ++scans_without_tomatoes_;
  auto& warned = warned_[static_cast<std::size_t>(miss)];
  if (warned) return;
  warned = true;
  logger().warn("scan not registered (warned once for this cause; scans_without_tomatoes counts them): {}", why);
}

void TomatoRegistrationNode::on_scan(const msgs::LineScan& m) {
  const bus::Time stamp = bus::Time::from_msg(m.header.stamp);
  if (!expected_) return skip(Miss::kNoneYet, "no expected_tomatoes received yet");
  if (expected_->frame_id != m.header.frame_id) {
    return skip(Miss::kOtherFrame, fmt::format("the expected_tomatoes are in frame '{}', the scan in '{}'",
                                               expected_->frame_id, m.header.frame_id));
  }
  if (const double age = std::abs(bus::to_seconds(stamp - expected_->stamp)); age > expectation_max_age_s_) {
    return skip(Miss::kStale, fmt::format("the expected_tomatoes (stamp {:.3f} s) are {:.3f} s from the scan "
                                          "(expectation_max_age_s {})",
                                          expected_->stamp.seconds(), age, expectation_max_age_s_));
  }
  auto out = std::make_unique<msgs::TrussRegistration>();
  out->header = m.header;
  out->expected_stamp = expected_->stamp.to_msg();
  if (!expected_->malformed.empty()) {
    out->reason = "expected_tomatoes malformed: " + expected_->malformed;
  } else if (const auto bad = nodes::to_core(m, scan_, min_reflectance_); !bad.empty()) {
    logger().warn("{}", bad);
    out->reason = bad;
  } else {
    TomatoRegistrationParams params = params_;
    if (expected_->max_shift_m > 0.0) params.max_shift_m = expected_->max_shift_m;  // checked by the core
    const TomatoRegistration r = register_tomatoes(scan_, expected_->tomatoes, params);
    out->ok = r.status.ok();
    out->reason = r.status.ok() ? r.note : r.status.message;
    out->shift_x_m = r.shift_xz_m.x();
    out->shift_z_m = r.shift_xz_m.y();
    out->tomatoes_in_plane = r.tomatoes_in_plane;
    out->tomatoes_matched = r.tomatoes_matched;
    out->inliers = r.inliers;
    out->rms_m = r.rms_m;
    out->support = r.support;
    out->runner_up_support = r.runner_up_support;
    out->violations = r.violations;
    out->runner_up_shift_x_m = r.runner_up_shift_xz_m.x();
    out->runner_up_shift_z_m = r.runner_up_shift_xz_m.y();
  }
  pub_->publish(std::move(out));
}

// ---------------------------------------------------------------------------- reflectance_clusterer

ReflectanceClustererNode::ReflectanceClustererNode(bus::NodeOptions o)
    : Node(std::move(o)),
      params_(bus::declared_settings<ReflectanceClusteringParams>(*this)),
      topics_(*this, [this](const LineScan& scan, msgs::LineClusters& out) {
        nodes::to_msg(cluster_by_reflectance(scan, params_), out);
      }) {}

// ---------------------------------------------------------------------------- alignment_search

AlignmentSearchNode::AlignmentSearchNode(bus::NodeOptions o)
    : Node(std::move(o)),
      surface_(bus::declared_settings<SurfaceReflectanceParams>(*this)),
      params_(bus::declared_settings<AlignmentParams>(*this)) {
  min_reflectance_ = nodes::declare_min_reflectance(*this);
  joint_ = declare_parameter<std::string>("pitch_joint", "gripper_pitch",
                                          "joint of sensor_msgs/JointState whose position is the gripper pitch [rad]");
  window_s_ = declare_parameter("window_s", 10.0, "samples older than this (vs the newest scan) leave the sweep [s]",
                                ParamConstraints::range(0.01, 3600.0));
  max_joint_age_s_ =
      declare_parameter("max_joint_age_s", 0.05, "a scan needs a pitch reading within this of its stamp [s]",
                        ParamConstraints::range(0.0, 10.0));
  pub_ = create_publisher<msgs::AlignmentResult>("alignment");
  joints_sub_ = create_subscription<sensor_msgs::msg::JointState>(
      "joint_states", bus::QoS::keep_last(50), [this](const sensor_msgs::msg::JointState& m) { on_joints(m); });
  sub_ = create_subscription<msgs::LineScan>("scan", bus::QoS::keep_last(kScanQueue),
                                             [this](const msgs::LineScan& m) { on_scan(m); });
}

void AlignmentSearchNode::on_joints(const sensor_msgs::msg::JointState& m) {
  const auto it = std::find(m.name.begin(), m.name.end(), joint_);
  if (it == m.name.end()) return;
  const auto k = static_cast<std::size_t>(it - m.name.begin());
  if (k >= m.position.size() || !std::isfinite(m.position[k])) return;
  pitch_.emplace_back(bus::Time::from_msg(m.header.stamp), m.position[k]);
  while (pitch_.size() > 200) pitch_.pop_front();
}

void AlignmentSearchNode::on_scan(const msgs::LineScan& m) {
  auto out = std::make_unique<msgs::AlignmentResult>();
  out->header = m.header;
  const bus::Time stamp = bus::Time::from_msg(m.header.stamp);
  auto publish_invalid = [&](std::string why) {
    out->outcome = msgs::AlignmentResult::INVALID_INPUT;
    out->reason = std::move(why);
    out->num_samples = static_cast<std::uint32_t>(samples_.size());
    pub_->publish(std::move(out));
  };
  if (const auto bad = nodes::to_core(m, scan_, min_reflectance_); !bad.empty()) {
    logger().warn("{}", bad);
    return publish_invalid(bad);
  }
  // The pitch at the scan's stamp: the nearest joint reading, if close enough.
  const std::pair<bus::Time, double>* nearest = nullptr;
  for (const auto& p : pitch_) {
    if (!nearest || std::abs(bus::to_seconds(p.first - stamp)) < std::abs(bus::to_seconds(nearest->first - stamp))) {
      nearest = &p;
    }
  }
  if (!nearest || std::abs(bus::to_seconds(nearest->first - stamp)) > max_joint_age_s_) {
    return publish_invalid("no '" + joint_ + "' reading within max_joint_age_s of the scan");
  }
  const SurfaceReflectance s = surface_reflectance(scan_, surface_);
  if (!s.status.ok()) return publish_invalid("no surface reflectance in the scan: " + s.status.message);
  samples_.emplace_back(stamp, AlignmentSample{nearest->second, s.reflectance});
  while (!samples_.empty() && bus::to_seconds(stamp - samples_.front().first) > window_s_) samples_.pop_front();
  std::vector<AlignmentSample> sweep;
  for (const auto& [t, sample] : samples_) sweep.push_back(sample);
  const auto a = find_alignment(sweep, params_);
  out->outcome = wire(a.outcome);
  out->reason = a.status.ok() ? a.note : a.status.message;
  out->best_pitch_rad = a.best_pitch_rad;
  out->peak_reflectance = a.peak_reflectance;
  out->refined = a.refined;
  out->num_samples = static_cast<std::uint32_t>(a.num_samples);
  out->last_pitch_rad = nearest->second;
  out->last_reflectance = s.reflectance;
  pub_->publish(std::move(out));
}

// ---------------------------------------------------------------------------- pitch_sweep

PitchSweepNode::PitchSweepNode(bus::NodeOptions o) : Node(std::move(o)) {
  joint_ = declare_parameter<std::string>("pitch_joint", "gripper_pitch", "the joint commanded [rad]");
  const double from =
      declare_parameter("from_deg", -16.0, "first pitch of the sweep [deg]", ParamConstraints::range(-90.0, 90.0));
  const double to =
      declare_parameter("to_deg", 16.0, "last pitch of the sweep [deg]", ParamConstraints::range(-90.0, 90.0));
  const double step = declare_parameter("step_deg", 2.0, "pitch step [deg]", ParamConstraints::range(0.01, 90.0));
  const double dwell =
      declare_parameter("dwell_s", 0.3, "time at each pitch: several scans [s]", ParamConstraints::range(0.001, 60.0));
  if (!(to > from)) {
    throw bus::ParamError({}, fmt::format("node '{}': to_deg ({}) must be above from_deg ({})", full_name(), to, from));
  }
  const int steps = static_cast<int>(std::floor((to - from) / step + 1e-9));
  if (steps < 2) {
    throw bus::ParamError({}, fmt::format("node '{}': the sweep {}..{} deg in {} deg steps has {} pitches; the "
                                          "alignment search needs at least 3",
                                          full_name(), from, to, step, steps + 1));
  }
  for (int k = 0; k <= steps; ++k) pitches_rad_.push_back((from + k * step) * std::numbers::pi / 180.0);
  command_pub_ = create_publisher<sensor_msgs::msg::JointState>("joint_command", bus::QoS::keep_last(10));
  aligned_pub_ = create_publisher<msgs::AlignmentResult>("aligned", bus::QoS::keep_last(10));
  alignment_sub_ = create_subscription<msgs::AlignmentResult>("alignment", bus::QoS::keep_last(kScanQueue),
                                                              [this](const msgs::AlignmentResult& m) { latest_ = m; });
  // One step per period: the first command one dwell after start, the
  // verdict one dwell after the last (its scans are in by then).
  timer_ = create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(dwell * 1e9)), [this] { tick(); });
}

void PitchSweepNode::command(double pitch_rad) {
  auto m = std::make_unique<sensor_msgs::msg::JointState>();
  m->header.stamp = now().to_msg();
  m->name = {joint_};
  m->position = {pitch_rad};
  command_pub_->publish(std::move(m));
}

void PitchSweepNode::tick() {
  if (state_ == State::kDone) return;
  if (next_ < pitches_rad_.size()) {
    command(pitches_rad_[next_++]);
    return;
  }
  state_ = State::kDone;
  timer_->cancel();
  auto out = std::make_unique<msgs::AlignmentResult>();
  if (latest_)
    *out = *latest_;
  else {
    out->outcome = msgs::AlignmentResult::INVALID_INPUT;
    out->reason = "no alignment result arrived during the sweep (is alignment_search running on this scan?)";
  }
  out->header.stamp = now().to_msg();
  if (out->outcome == msgs::AlignmentResult::FOUND) {
    command(out->best_pitch_rad);
    logger().info("aligned: pitch {:.2f} deg ({} samples, peak reflectance {:.1f})",
                  out->best_pitch_rad * 180.0 / std::numbers::pi, out->num_samples, out->peak_reflectance);
  } else {
    logger().warn("sweep ended without an alignment: {}", out->reason);
  }
  aligned_pub_->publish(std::move(out));
}

// ---------------------------------------------------------------------------- registry

void register_nodes(bus::NodeRegistry& r) {
  r.add<LineClustererNode>("laser_clustering", "line_clusterer",
                           "two-stage DBSCAN of line scans (scan -> clusters), thesis 4.4.2");
  r.add<PedicelFinderNode>("laser_clustering", "pedicel_finder",
                           "pedicel and the scissor move that centres it (scan -> pedicel, clusters)");
  r.add<TomatoRegistrationNode>("laser_clustering", "tomato_registration",
                                "the vision's tomatoes registered on a scan through them: its common offset "
                                "(scan + expected_tomatoes -> truss_registration)");
  r.add<ReflectanceClustererNode>("laser_clustering", "reflectance_clusterer",
                                  "DBSCAN on position and reflectance (scan -> clusters), thesis 5.3");
  r.add<AlignmentSearchNode>("laser_clustering", "alignment_search",
                             "pitch of maximum surface reflectance (scan + joint_states -> alignment), 5.3.2");
  r.add<PitchSweepNode>("laser_clustering", "pitch_sweep",
                        "sweeps the gripper pitch (joint_command), then commands the pitch alignment found, 5.3.2");
}

}  // namespace tinyline::laser_clustering
