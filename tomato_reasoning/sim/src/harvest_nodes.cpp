// SPDX-License-Identifier: Apache-2.0
// The simulator's hand and referee in the harvesting demo
// (launch/tomato_harvest.launch.yaml):
//
// tomato_reasoning/sim_gripper   the robot hand in the truss_camera's truss:
//     the tiny laser on it and the scissors. On `pick_pose` (PoseStamped,
//     camera frame) it scans from that pose (the project's TOF sensor model
//     and the driver's processing) and publishes `scan` (LineScan); on `cut`
//     (CutCommand) it closes the blades there (sim/scenes/cutter.hpp) and
//     publishes `cut_outcome` (CutOutcome, with the truth: which truss
//     tomato the target is and whose fruit fell); a fruit whose pedicel is
//     cut leaves its world.
// tomato_reasoning/harvest_score the harvest scored against the truss's truth
//     as the thesis's Table 4.2 counts it: on the pick_verifier's `summary`
//     (HarvestSummary) and the `cut_outcome` of every pick that closed the
//     blades (the two topics arrive in either order) it logs the
//     row beside the thesis's and publishes `score` (HarvestScore); the
//     demo's launch ends when it does.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/eigen.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/tinyline_msgs/cut_command.hpp>
#include <tinyline/msg/tinyline_msgs/cut_outcome.hpp>
#include <tinyline/msg/tinyline_msgs/harvest_score.hpp>
#include <tinyline/msg/tinyline_msgs/harvest_summary.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>

#include "scanner.hpp"
#include <tomato_reasoning/eval/verification.hpp>

#include "truss_parts.hpp"

namespace tinyline::tomato_reasoning::sim_nodes {

namespace msgs = tinyline_msgs::msg;
namespace te = tomato_reasoning::eval;
using bus::ParamConstraints;

namespace {

Eigen::Vector3d eig(const geometry_msgs::msg::Point& p) { return {p.x, p.y, p.z}; }

bool finite_pose(const geometry_msgs::msg::Pose& p) {
  const auto& q = p.orientation;
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return std::isfinite(p.position.x) && std::isfinite(p.position.y) && std::isfinite(p.position.z) &&
         std::isfinite(n) && std::abs(n - 1.0) < 1e-3;
}

std::uint8_t to_msg(sim::CutResult r) {
  static_assert(int(sim::CutResult::kCutTarget) == msgs::CutOutcome::CUT_TARGET);
  static_assert(int(sim::CutResult::kCutOtherPedicel) == msgs::CutOutcome::CUT_OTHER_PEDICEL);
  static_assert(int(sim::CutResult::kClosedOnNothing) == msgs::CutOutcome::CLOSED_ON_NOTHING);
  static_assert(int(sim::CutResult::kJammed) == msgs::CutOutcome::JAMMED);
  return static_cast<std::uint8_t>(r);
}

}  // namespace

class SimGripperNode : public bus::Node {
 public:
  explicit SimGripperNode(bus::NodeOptions o) : Node(std::move(o)) {
    class_ = truss_class(*this, declare_parameter<std::string>("truss_class", "B", "the truss_camera's class"));
    seed_ = declare_parameter("seed", 1, "the truss_camera's seed", ParamConstraints::range(0, 1 << 30));
    physics_ =
        truss_physics(*this, declare_parameter<std::string>("physics", kDefaultPhysics, "the truss_camera's physics"));
    frame_id_ = declare_parameter<std::string>("frame_id", "hand_laser", "frame of the published scans");
    scan_pub_ = create_publisher<msgs::LineScan>("scan");
    cut_pub_ = create_publisher<msgs::CutOutcome>("cut_outcome", bus::QoS::keep_last(16));
    pose_sub_ = create_subscription<geometry_msgs::msg::PoseStamped>(
        "pick_pose", bus::QoS::keep_last(2), [this](const geometry_msgs::msg::PoseStamped& m) { on_pose(m); });
    cut_sub_ = create_subscription<msgs::CutCommand>("cut", bus::QoS::keep_last(8),
                                                     [this](const msgs::CutCommand& m) { on_cut(m); });
  }
  void on_start() override {
    sim::TrussParams p;
    p.complexity = class_;
    p.seed = std::uint64_t(seed_);
    p.physics = physics_;
    sim::TrussWorld built = sim::make_truss_world(p);  // the truss_camera's truss
    truss_ = std::move(built.truss);
    world_ = std::move(built.world);
    scanner_ = te::make_hand_laser(te::VerificationOptions{});  // the hand laser the scoring uses
    logger().info("hand laser: {}", scanner_->describe());
  }

 private:
  void on_pose(const geometry_msgs::msg::PoseStamped& m) {
    const Eigen::Isometry3d T_world_laser = truss_.T_world_camera * tinyline::msg::to_isometry(m.pose);
    const auto s = scanner_->scan(world_, T_world_laser, index_);
    auto out = std::make_unique<msgs::LineScan>();
    out->header.stamp = m.header.stamp;  // the scan answers this pose
    out->header.frame_id = frame_id_;
    out->set_index = std::uint32_t(index_++);
    const std::size_t n = s.scan.size();
    out->angles.resize(n);
    out->distance_m.resize(n);
    out->status.resize(n);
    out->reflectance.resize(s.scan.reflectance.size());
    for (std::size_t i = 0; i < n; ++i) {
      out->angles[i] = float(s.scan.angle_rad[i]);
      const bool valid = s.scan.valid(i);
      out->distance_m[i] = valid ? float(s.scan.range_m[i]) : std::numeric_limits<float>::quiet_NaN();
      out->status[i] = valid ? msgs::LineScan::STATUS_VALID : msgs::LineScan::STATUS_TOO_DARK;
    }
    for (std::size_t i = 0; i < out->reflectance.size(); ++i) out->reflectance[i] = float(s.scan.reflectance[i]);
    scan_pub_->publish(std::move(out));
  }

  void on_cut(const msgs::CutCommand& c) {
    auto out = std::make_unique<msgs::CutOutcome>();
    out->header = c.header;
    out->tomato = c.tomato;
    out->pick_rank = c.pick_rank;
    out->attempt = c.attempt;
    const Eigen::Vector3d target_world = truss_.T_world_camera * eig(c.target_centre);
    out->target_truth = target_world.allFinite() ? match_truth(truss_, target_world) : -1;
    sim::CutOutcome r;
    if (!finite_pose(c.laser_pose) || !std::isfinite(c.throat_z_m)) {
      r.result = sim::CutResult::kJammed;  // a hand sent nowhere closes on nothing it can report
      r.object = "invalid laser pose or throat (not finite, or not a unit quaternion)";
    } else {
      const Eigen::Isometry3d T_world_laser = truss_.T_world_camera * tinyline::msg::to_isometry(c.laser_pose);
      // A target that is no truss tomato: whatever is cut is another's pedicel.
      const int target = out->target_truth >= 0 ? out->target_truth : static_cast<int>(truss_.tomatoes.size());
      r = sim::close_blades(truss_, sim::throat_from_laser(T_world_laser, c.throat_z_m), blades_, target);
    }
    out->result = to_msg(r.result);
    out->object = r.object;
    for (int i : r.severed) {  // the fruit falls out of the hand laser's world
      (void)sim::drop_tomato(world_, truss_, i);
      sim::drop_tomato(truss_, i);
      out->fallen.push_back(i);
    }
    logger().info("blades closed for pick {} (truss tomato {}): {}{}", c.pick_rank + 1, out->target_truth,
                  sim::to_string(r.result), r.object.empty() ? "" : " on " + r.object);
    cut_pub_->publish(std::move(out));
  }

  sim::TrussClass class_ = sim::TrussClass::kB;
  int seed_ = 1;
  sim::TrussPhysics physics_ = sim::TrussPhysics::kElasticRod;
  std::string frame_id_;
  sim::Truss truss_;
  sim::World world_;
  sim::BladeParams blades_;
  std::unique_ptr<laser_clustering::eval::Scanner> scanner_;
  std::uint64_t index_ = 0;
  std::shared_ptr<bus::Publisher<msgs::LineScan>> scan_pub_;
  std::shared_ptr<bus::Publisher<msgs::CutOutcome>> cut_pub_;
  std::shared_ptr<bus::Subscription<geometry_msgs::msg::PoseStamped>> pose_sub_;
  std::shared_ptr<bus::Subscription<msgs::CutCommand>> cut_sub_;
};

namespace {

// Thesis Table 4.2 (trials, SD, SP(1), SP(2), HS, CF) per complexity class.
struct ThesisRow {
  int trials, sd, sp1, sp2, hs, cf;
};
ThesisRow thesis_row(sim::TrussClass c) {
  switch (c) {
    case sim::TrussClass::kA: return {36, 36, 26, 4, 3, 3};
    case sim::TrussClass::kB: return {57, 49, 30, 10, 11, 6};
    case sim::TrussClass::kC: return {43, 33, 17, 9, 13, 4};
  }
  return {};
}

// Every detected tomato has exactly one pick; empty when so, else why not.
std::string unaccounted(const msgs::HarvestSummary& s) {
  std::vector<int> seen(s.detected, 0);
  for (const auto& p : s.picks) {
    if (p.tomato < 0 || std::size_t(p.tomato) >= seen.size())
      return "pick " + std::to_string(p.pick_rank + 1) + " is for tomato " + std::to_string(p.tomato) +
             ", not one of the " + std::to_string(s.detected) + " detected";
    if (++seen[std::size_t(p.tomato)] > 1) return "tomato " + std::to_string(p.tomato) + " has more than one pick";
  }
  for (std::size_t k = 0; k < seen.size(); ++k)
    if (seen[k] == 0) return "tomato " + std::to_string(k) + " has no pick";
  return {};
}

}  // namespace

class HarvestScoreNode : public bus::Node {
 public:
  explicit HarvestScoreNode(bus::NodeOptions o) : Node(std::move(o)) {
    class_ = truss_class(*this, declare_parameter<std::string>("truss_class", "B", "the truss_camera's class"));
    seed_ = declare_parameter("seed", 1, "the truss_camera's seed", ParamConstraints::range(0, 1 << 30));
    physics_ =
        truss_physics(*this, declare_parameter<std::string>("physics", kDefaultPhysics, "the truss_camera's physics"));
    score_pub_ = create_publisher<msgs::HarvestScore>("score", bus::QoS::keep_last(4));
    cut_sub_ = create_subscription<msgs::CutOutcome>("cut_outcome", bus::QoS::keep_last(64),
                                                     [this](const msgs::CutOutcome& m) {
                                                       cuts_[m.pick_rank] = m;
                                                       score_when_ready();
                                                     });
    summary_sub_ = create_subscription<msgs::HarvestSummary>("summary", bus::QoS::keep_last(4),
                                                             [this](const msgs::HarvestSummary& m) {
                                                               summary_ = m;
                                                               score_when_ready();
                                                             });
  }
  void on_start() override {
    sim::TrussParams p;
    p.complexity = class_;
    p.seed = std::uint64_t(seed_);
    p.physics = physics_;
    truss_ = sim::make_truss(p);
  }

 private:
  // Picked on its own pick: the gripper cut the target, and the target is a
  // truss tomato whose fruit fell.
  bool picked_truly(const msgs::HarvestPick& p) const {
    const auto it = cuts_.find(p.pick_rank);
    if (p.outcome != msgs::HarvestPick::PICKED || it == cuts_.end()) return false;
    const auto& c = it->second;
    return c.result == msgs::CutOutcome::CUT_TARGET && c.target_truth >= 0 &&
           std::find(c.fallen.begin(), c.fallen.end(), c.target_truth) != c.fallen.end();
  }

  // The summary and the gripper's report of every closing it counts arrive
  // on two topics, in either order: score once both are in.
  void score_when_ready() {
    if (!summary_ || scored_) return;
    for (const auto& p : summary_->picks) {
      if (p.outcome == msgs::HarvestPick::LEFT_FOR_HUMAN) continue;  // may never have closed the blades
      const auto it = cuts_.find(p.pick_rank);
      if (it == cuts_.end() || it->second.attempt != p.attempts) return;
    }
    scored_ = true;
    score(*summary_);
  }

  void score(const msgs::HarvestSummary& s) {
    auto out = std::make_unique<msgs::HarvestScore>();
    out->header = s.header;
    out->truss_class = std::string(1, char(class_));
    out->seed = std::uint32_t(seed_);
    out->trials = std::uint32_t(truss_.tomatoes.size());
    std::vector<int> detected(truss_.tomatoes.size(), 0);
    for (const auto& p : s.picks) {
      const int t = match_truth(truss_, truss_.T_world_camera * eig(p.centre));
      if (t >= 0) detected[std::size_t(t)] = 1;
      const bool picked = picked_truly(p);
      out->picked_first += picked && p.attempts == 1;
      out->picked_second += picked && p.attempts == 2;
      out->cut_failures += p.outcome == msgs::HarvestPick::CUT_FAILURE;
      logger().info("  pick {}: tomato {} is {}: {} after {} attempt(s)", p.pick_rank + 1, p.tomato,
                    t >= 0 ? "truss tomato " + std::to_string(t) : std::string("no truss tomato"),
                    picked                                   ? "picked"
                    : p.outcome == msgs::HarvestPick::PICKED ? "NOT picked (the truth disagrees)"
                                                             : "not picked",
                    p.attempts);
    }
    out->detected = std::uint32_t(std::count(detected.begin(), detected.end(), 1));
    out->human = out->trials - std::min(out->trials, out->picked_first + out->picked_second + out->cut_failures);
    out->reason = unaccounted(s);
    out->accounted = out->reason.empty();
    const ThesisRow t = thesis_row(class_);
    logger().info(
        "harvest score, class {} seed {} (thesis Table 4.2's columns): trials {}, SD {}, SP(1) {}, SP(2) {}, HS {}, CF "
        "{}",
        char(class_), seed_, out->trials, out->detected, out->picked_first, out->picked_second, out->human,
        out->cut_failures);
    logger().info("  thesis Table 4.2, class {}: trials {}, SD {}, SP(1) {}, SP(2) {}, HS {}, CF {}", char(class_),
                  t.trials, t.sd, t.sp1, t.sp2, t.hs, t.cf);
    if (out->accounted) {
      logger().info("harvest ended: every one of {} detected tomatoes accounted for", s.detected);
    } else {
      logger().error("harvest ended with a detected tomato unaccounted for: {}", out->reason);
    }
    score_pub_->publish(std::move(out));
  }

  sim::TrussClass class_ = sim::TrussClass::kB;
  int seed_ = 1;
  sim::TrussPhysics physics_ = sim::TrussPhysics::kElasticRod;
  sim::Truss truss_;
  std::map<int, msgs::CutOutcome> cuts_;  // the last closing of each pick, by rank
  std::optional<msgs::HarvestSummary> summary_;
  bool scored_ = false;
  std::shared_ptr<bus::Publisher<msgs::HarvestScore>> score_pub_;
  std::shared_ptr<bus::Subscription<msgs::CutOutcome>> cut_sub_;
  std::shared_ptr<bus::Subscription<msgs::HarvestSummary>> summary_sub_;
};

void register_harvest_nodes(bus::NodeRegistry& r) {
  r.add<SimGripperNode>(
      "tomato_reasoning", "sim_gripper",
      "simulated hand in the truss_camera's truss: pick_pose -> laser scan; cut -> the scissors close, "
      "cut_outcome (a cut fruit falls)");
  r.add<HarvestScoreNode>("tomato_reasoning", "harvest_score",
                          "the harvest's summary scored against the truss's truth as Table 4.2 counts it -> score");
}

}  // namespace tinyline::tomato_reasoning::sim_nodes
