// The simulator side of the harvesting demo (launch/tomato_harvest.launch.yaml):
//
// tomato_reasoning/truss_camera  a seeded truss of class A, B or C seen by the
//     simulated RGB-D camera: `cloud` (PointCloud2, organised XYZRGB in the
//     camera's optical frame) and `truth` (MarkerArray: the true spheres and
//     pedicels) at rate_hz. With `views: 2` also the second hand-camera view
//     of the thesis's robot (4.5; it orbits the truss by 35 deg): `cloud2`
//     and `cloud2_pose` (its pose in `cloud`'s frame as the robot knows it,
//     off by the calibration residual), published before `cloud` with the
//     same stamp.
// tomato_reasoning/hand_laser    the tiny laser on the hand in the same truss:
//     on `pick_pose` (PoseStamped, camera frame) it scans from that pose
//     (the project's TOF sensor model and the driver's processing) and
//     publishes `scan` (tinyline_msgs/LineScan); a `verification` that cuts
//     harvests the fruit (it leaves the world with its pedicel).
//
// Registered under tomato_reasoning/ (launch/tomato_harvest.launch.yaml); the
// scenario and the hand laser are the tomato evaluation's (tomato_reasoning/eval).
#include <cmath>
#include <limits>
#include <memory>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/pick_verification.hpp>
#include <tinyline/msg/visualization_msgs/marker_array.hpp>

#include <tinyline/msg/eigen.hpp>

#include <sim/eval/scanner.hpp>
#include <tomato_reasoning/eval/scenario.hpp>
#include <tomato_reasoning/eval/verification.hpp>
#include <tomato_reasoning/nodes/nodes.hpp>

#include "parts.hpp"

namespace tinyline::sim::nodes {

namespace msgs = tinyline_msgs::msg;
namespace te = tomato_reasoning::eval;
using bus::ParamConstraints;
using tomato_reasoning::nodes::to_msg;

namespace {

sim::TrussClass truss_class(const bus::Node& n, const std::string& s) {
  const auto c = sim::parse_truss_class(s);
  if (!c) throw bus::ParamError({}, "node '" + n.full_name() + "': truss_class '" + s + "' is not A, B or C");
  return *c;
}

}  // namespace

class TrussCameraNode : public bus::Node {
 public:
  explicit TrussCameraNode(bus::NodeOptions o) : Node(std::move(o)) {
    class_ = truss_class(*this, declare_parameter<std::string>("truss_class", "B", "complexity class of section 4.5: A, B or C"));
    seed_ = declare_parameter("seed", 1, "truss seed (the same seed gives the same truss)", ParamConstraints::range(0, 1 << 30));
    rate_hz_ = declare_parameter("rate_hz", 1.0, "frames per second", ParamConstraints::range(0.01, 30.0));
    frame_id_ = declare_parameter<std::string>("frame_id", "camera", "the camera's optical frame");
    views_ = declare_parameter("views", 1, "1: one hand-camera view (cloud); 2: also cloud2 and cloud2_pose",
                               ParamConstraints::range(1, 2));
    cloud_pub_ = create_publisher<sensor_msgs::msg::PointCloud2>("cloud");
    if (views_ == 2) {
      cloud2_pub_ = create_publisher<sensor_msgs::msg::PointCloud2>("cloud2");
      pose2_pub_ = create_publisher<geometry_msgs::msg::PoseStamped>("cloud2_pose");
    }
    truth_pub_ = create_publisher<visualization_msgs::msg::MarkerArray>("truth");
  }
  void on_start() override {
    te::ScenarioOptions so;
    so.views = views_;
    scenario_ = std::make_unique<te::Scenario>(te::make_scenario(class_, std::uint64_t(seed_), so));
    logger().info("truss class {} seed {}: {} tomatoes, camera {:.2f} m away, {} view(s)", char(class_), seed_,
                  scenario_->truth.size(), scenario_->truss.params.camera_distance_m, views_);
    // The first frame one period after start: every node (the recorder too) is listening by then.
    timer_ = create_timer(std::chrono::nanoseconds(std::int64_t(1e9 / rate_hz_)), [this] { tick(); });
  }

 private:
  void tick() {
    auto c = std::make_unique<sensor_msgs::msg::PointCloud2>();
    c->header.stamp = now().to_msg();
    c->header.frame_id = frame_id_;
    to_msg(scenario_->cloud(), *c);
    if (views_ == 2) {
      // The second view first: the detector fuses when the reference cloud arrives.
      auto c2 = std::make_unique<sensor_msgs::msg::PointCloud2>();
      c2->header.stamp = c->header.stamp;
      c2->header.frame_id = frame_id_ + "_2";
      to_msg(scenario_->clouds[1], *c2);
      auto p2 = std::make_unique<geometry_msgs::msg::PoseStamped>();
      p2->header.stamp = c->header.stamp;
      p2->header.frame_id = frame_id_;
      p2->pose = tinyline::msg::to_pose(scenario_->T_ref_camera[1]);
      cloud2_pub_->publish(std::move(c2));
      pose2_pub_->publish(std::move(p2));
    }
    auto t = std::make_unique<visualization_msgs::msg::MarkerArray>();
    for (std::size_t i = 0; i < scenario_->truth.size(); ++i) {
      const auto& x = scenario_->truth[i];
      visualization_msgs::msg::Marker m;
      m.header = c->header;
      m.ns = "truth_pedicels";
      m.id = int(i);
      m.type = visualization_msgs::msg::Marker::ARROW;
      m.pose.orientation.w = 1;
      geometry_msgs::msg::Point a, b;
      const Eigen::Vector3d p0 = x.centre_m + x.radius_m * x.pedicel_dir, p1 = p0 + 0.04 * x.pedicel_dir;
      a.x = p0.x(), a.y = p0.y(), a.z = p0.z();
      b.x = p1.x(), b.y = p1.y(), b.z = p1.z();
      m.points = {a, b};
      m.scale.x = 0.002, m.scale.y = 0.004, m.scale.z = 0.006;
      m.color.r = 1, m.color.g = 1, m.color.b = 1, m.color.a = 0.8f;
      t->markers.push_back(m);
    }
    cloud_pub_->publish(std::move(c));
    truth_pub_->publish(std::move(t));
  }
  sim::TrussClass class_ = sim::TrussClass::kB;
  int seed_ = 1;
  double rate_hz_ = 1.0;
  int views_ = 1;
  std::string frame_id_;
  std::unique_ptr<te::Scenario> scenario_;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::PointCloud2>> cloud_pub_, cloud2_pub_;
  std::shared_ptr<bus::Publisher<geometry_msgs::msg::PoseStamped>> pose2_pub_;
  std::shared_ptr<bus::Publisher<visualization_msgs::msg::MarkerArray>> truth_pub_;
  std::shared_ptr<bus::Timer> timer_;
};

class HandLaserNode : public bus::Node {
 public:
  explicit HandLaserNode(bus::NodeOptions o) : Node(std::move(o)) {
    class_ = truss_class(*this, declare_parameter<std::string>("truss_class", "B", "the truss_camera's class"));
    seed_ = declare_parameter("seed", 1, "the truss_camera's seed", ParamConstraints::range(0, 1 << 30));
    frame_id_ = declare_parameter<std::string>("frame_id", "hand_laser", "frame of the published scans");
    scan_pub_ = create_publisher<msgs::LineScan>("scan");
    pose_sub_ = create_subscription<geometry_msgs::msg::PoseStamped>(
        "pick_pose", bus::QoS::keep_last(2), [this](const geometry_msgs::msg::PoseStamped& m) { on_pose(m); });
    verification_sub_ = create_subscription<msgs::PickVerification>(
        "verification", bus::QoS::keep_last(16), [this](const msgs::PickVerification& m) { on_verification(m); });
  }
  void on_start() override {
    sim::TrussParams p;
    p.complexity = class_;
    p.seed = std::uint64_t(seed_);
    truss_ = sim::make_truss(p);
    (void)sim::add_to_world(truss_, world_);
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
  void on_verification(const msgs::PickVerification& v) {
    if (v.outcome != msgs::PickVerification::CUT_HERE && v.outcome != msgs::PickVerification::MOVE) return;
    // Harvest the fruit whose pedicel the blades closed on: the calyx nearest the cut.
    const Eigen::Isometry3d T_cam_world = truss_.T_world_camera.inverse();
    const Eigen::Vector3d cut(v.cut_point.x, v.cut_point.y, v.cut_point.z);
    int best = -1;
    double best_d = 0.06;
    for (std::size_t t = 0; t < truss_.tomatoes.size(); ++t) {
      const double d = (T_cam_world * truss_.tomatoes[t].calyx_m - cut).norm();
      if (d < best_d) best = int(t), best_d = d;
    }
    if (best < 0) return;
    const std::string& name = truss_.tomatoes[std::size_t(best)].object_name;
    const std::string idx = name.substr(name.rfind('_') + 1), prefix = truss_.params.name + "_";
    for (std::size_t o = 0; o < world_.size(); ++o) {
      const auto id = static_cast<sim::ObjectId>(o);
      const std::string& n = world_.object(id).name;
      if (n.rfind(name, 0) == 0 || n == prefix + "pedicel_" + idx || n == prefix + "calyx_" + idx) {
        Eigen::Isometry3d far = world_.object(id).T_world_object;
        far.translation() += Eigen::Vector3d(0, 0, -100);
        world_.set_pose(id, far);
      }
    }
  }
  sim::TrussClass class_ = sim::TrussClass::kB;
  int seed_ = 1;
  std::string frame_id_;
  sim::Truss truss_;
  sim::World world_;
  std::unique_ptr<eval::Scanner> scanner_;
  std::uint64_t index_ = 0;
  std::shared_ptr<bus::Publisher<msgs::LineScan>> scan_pub_;
  std::shared_ptr<bus::Subscription<geometry_msgs::msg::PoseStamped>> pose_sub_;
  std::shared_ptr<bus::Subscription<msgs::PickVerification>> verification_sub_;
};

void register_truss_nodes(bus::NodeRegistry& r) {
  r.add<TrussCameraNode>("tomato_reasoning", "truss_camera",
                         "simulated RGB-D camera on a seeded tomato truss (class A/B/C): cloud + truth markers");
  r.add<HandLaserNode>("tomato_reasoning", "hand_laser",
                       "simulated tiny laser on the hand in the same truss: pick_pose -> scan; harvests verified cuts");
}

}  // namespace tinyline::sim::nodes
