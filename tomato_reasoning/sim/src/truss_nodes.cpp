// SPDX-License-Identifier: Apache-2.0
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
//     A `cut_outcome` (CutOutcome) whose fruit fell takes those fruit out
//     of the camera's world: the next frames no longer show them.
// (The hand, tomato_reasoning/sim_gripper, and the referee,
// tomato_reasoning/harvest_score: harvest_nodes.cpp.)
//
// Registered under tomato_reasoning/ (launch/tomato_harvest.launch.yaml); the
// scenario and the hand laser are the tomato evaluation's (tomato_reasoning/eval).
#include <cmath>
#include <limits>
#include <memory>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/tinyline_msgs/cut_outcome.hpp>
#include <tinyline/msg/visualization_msgs/marker_array.hpp>

#include <tinyline/msg/eigen.hpp>

#include <tomato_reasoning/eval/scenario.hpp>
#include <tomato_reasoning/nodes/nodes.hpp>

#include <tomato_reasoning/sim/register.hpp>

#include "truss_parts.hpp"

namespace tinyline::tomato_reasoning::sim_nodes {

namespace msgs = tinyline_msgs::msg;
namespace te = tomato_reasoning::eval;
using bus::ParamConstraints;
using tomato_reasoning::nodes::to_msg;

class TrussCameraNode : public bus::Node {
 public:
  explicit TrussCameraNode(bus::NodeOptions o) : Node(std::move(o)) {
    class_ = truss_class(
        *this, declare_parameter<std::string>("truss_class", "B", "complexity class of section 4.5: A, B or C"));
    seed_ = declare_parameter("seed", 1, "truss seed (the same seed gives the same truss)",
                              ParamConstraints::range(0, 1 << 30));
    rate_hz_ = declare_parameter("rate_hz", 1.0, "frames per second", ParamConstraints::range(0.01, 30.0));
    frame_id_ = declare_parameter<std::string>("frame_id", "camera", "the camera's optical frame");
    views_ = declare_parameter("views", 1, "1: one hand-camera view (cloud); 2: also cloud2 and cloud2_pose",
                               ParamConstraints::range(1, 2));
    physics_ = truss_physics(*this, declare_parameter<std::string>("physics", kDefaultPhysics,
                                                                   "the truss's physics: elastic_rod or pendulum"));
    cloud_pub_ = create_publisher<sensor_msgs::msg::PointCloud2>("cloud");
    if (views_ == 2) {
      cloud2_pub_ = create_publisher<sensor_msgs::msg::PointCloud2>("cloud2");
      pose2_pub_ = create_publisher<geometry_msgs::msg::PoseStamped>("cloud2_pose");
    }
    truth_pub_ = create_publisher<visualization_msgs::msg::MarkerArray>("truth");
    cut_sub_ = create_subscription<msgs::CutOutcome>("cut_outcome", bus::QoS::keep_last(16),
                                                     [this](const msgs::CutOutcome& m) { on_cut(m); });
  }
  void on_start() override {
    te::ScenarioOptions so;
    so.views = views_;
    so.truss.physics = physics_;
    scenario_ = std::make_unique<te::Scenario>(te::make_scenario(class_, std::uint64_t(seed_), so));
    logger().info("truss class {} seed {}: {} tomatoes, camera {:.2f} m away, {} view(s)", char(class_), seed_,
                  scenario_->truth.size(), scenario_->truss.params.camera_distance_m, views_);
    // The first frame one period after start: every node (the recorder too) is listening by then.
    timer_ = create_timer(std::chrono::nanoseconds(std::int64_t(1e9 / rate_hz_)), [this] { tick(); });
  }

 private:
  void on_cut(const msgs::CutOutcome& m) {
    for (int i : m.fallen) {
      if (i < 0 || std::size_t(i) >= scenario_->truss.tomatoes.size() || sim::dropped(scenario_->truss, i)) continue;
      (void)sim::drop_tomato(scenario_->world, scenario_->truss, i);
      sim::drop_tomato(scenario_->truss, i);
      stale_ = true;
    }
  }
  // The views again, without the fruit that fell (the same noise as before).
  void render_again() {
    const sim::RgbdCamera camera(te::ScenarioOptions{}.camera);
    for (std::size_t v = 0; v < scenario_->frames.size(); ++v) {
      scenario_->frames[v] =
          camera.render(scenario_->world, scenario_->frames[v].T_world_camera, scenario_->seed * 16 + v);
      scenario_->clouds[v] = te::to_cloud(scenario_->frames[v]);
    }
    stale_ = false;
  }
  void tick() {
    if (stale_) render_again();
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
      if (sim::dropped(scenario_->truss, int(i))) continue;
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
  sim::TrussPhysics physics_ = sim::TrussPhysics::kElasticRod;
  double rate_hz_ = 1.0;
  int views_ = 1;
  std::string frame_id_;
  std::unique_ptr<te::Scenario> scenario_;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::PointCloud2>> cloud_pub_, cloud2_pub_;
  std::shared_ptr<bus::Publisher<geometry_msgs::msg::PoseStamped>> pose2_pub_;
  std::shared_ptr<bus::Publisher<visualization_msgs::msg::MarkerArray>> truth_pub_;
  std::shared_ptr<bus::Subscription<msgs::CutOutcome>> cut_sub_;
  std::shared_ptr<bus::Timer> timer_;
  bool stale_ = false;  ///< fruit fell since the frames were rendered
};

}  // namespace tinyline::tomato_reasoning::sim_nodes

namespace tinyline::tomato_reasoning {

void register_sim_nodes(bus::NodeRegistry& r) {
  r.add<sim_nodes::TrussCameraNode>(
      "tomato_reasoning", "truss_camera",
      "simulated RGB-D camera on a seeded tomato truss (class A/B/C): cloud + truth markers; cut fruit leave it");
  sim_nodes::register_harvest_nodes(r);
}

}  // namespace tinyline::tomato_reasoning
