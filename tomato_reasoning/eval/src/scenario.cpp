// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/scenario.hpp"

#include <cmath>
#include <limits>
#include <string>

#include <tinyline/common/random.hpp>

namespace tinyline::tomato_reasoning::eval {

ColorCloud to_cloud(const sim::RgbdFrame& f) {
  ColorCloud c;
  c.width = f.width;
  c.height = f.height;
  c.xyz.resize(f.size());
  c.rgb = f.rgb;
  for (std::size_t i = 0; i < f.size(); ++i) c.xyz[i] = f.point(i);
  return c;
}

namespace {
using common::splitmix64;
double unit_normal(std::uint64_t key) {
  const double u1 = common::unit_open(splitmix64(key));
  const double u2 = common::unit_open(splitmix64(key + 1));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// The test conditions of ScenarioOptions on one rendered frame's cloud.
void apply_conditions(const ScenarioOptions& o, const sim::World& world, const sim::RgbdFrame& f, std::uint64_t key,
                      ColorCloud& c) {
  if (o.drop_pedicel_depth) {
    std::vector<std::uint8_t> thin(world.size(), 0);
    for (std::size_t k = 0; k < world.size(); ++k) {
      const std::string& n = world.object(static_cast<sim::ObjectId>(k)).name;
      thin[k] = n.find("_pedicel_") != std::string::npos || n.find("_calyx_") != std::string::npos;
    }
    for (std::size_t i = 0; i < f.size(); ++i)
      if (f.object[i] != sim::kNoObject && thin[static_cast<std::size_t>(f.object[i])])
        c.xyz[i].setConstant(std::numeric_limits<float>::quiet_NaN());
  }
  if (o.extra_depth_noise_m > 0) {
    for (std::size_t i = 0; i < c.size(); ++i) {
      if (!c.xyz[i].allFinite()) continue;
      const float z = c.xyz[i].z();
      const float dz = static_cast<float>(o.extra_depth_noise_m * unit_normal(splitmix64(key + 2 * i)));
      c.xyz[i] *= (z + dz) / z;  // along the ray: depth and the point scale together
    }
  }
}
}  // namespace

Scenario make_scenario(sim::TrussClass complexity, std::uint64_t seed, const ScenarioOptions& o) {
  Scenario s;
  s.complexity = complexity;
  s.seed = seed;
  sim::TrussParams p = o.truss;
  p.complexity = complexity;
  p.seed = seed;
  sim::TrussWorld built = sim::make_truss_world(p);
  s.truss = std::move(built.truss);
  s.world = std::move(built.world);
  const std::vector<sim::TrussTomato>& second = built.distractors;
  const sim::RgbdCamera camera(o.camera);
  std::vector<Eigen::Isometry3d> T_world_camera{s.truss.T_world_camera};
  if (o.views >= 2) {
    // Orbit the fruit's centroid about the vertical, away from the first view's yaw.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& t : s.truss.tomatoes) mean += t.centre_m;
    mean /= static_cast<double>(s.truss.tomatoes.size());
    const Eigen::Vector3d eye0 = s.truss.T_world_camera.translation();
    const double side = (eye0 - mean).x() > 0 ? -1.0 : 1.0;
    const Eigen::AngleAxisd orbit(side * o.second_view_yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ());
    const Eigen::Vector3d eye1 = mean + orbit * (eye0 - mean);
    T_world_camera.push_back(sim::look_at(eye1, mean));
  }
  const Eigen::Isometry3d T_ref_world = T_world_camera.front().inverse();
  for (std::size_t v = 0; v < T_world_camera.size(); ++v) {
    s.frames.push_back(camera.render(s.world, T_world_camera[v], seed * 16 + v));
    s.clouds.push_back(to_cloud(s.frames.back()));
    apply_conditions(o, s.world, s.frames.back(), splitmix64(seed * 7919 + v) << 20, s.clouds.back());
    Eigen::Isometry3d T = T_ref_world * T_world_camera[v];
    if (v > 0) {
      // The pose the pipeline believes: off by the calibration residual.
      const std::uint64_t key = splitmix64(seed * 977 + v);
      const Eigen::Vector3d dt(unit_normal(key), unit_normal(key + 10), unit_normal(key + 20));
      const Eigen::Vector3d dr(unit_normal(key + 30), unit_normal(key + 40), unit_normal(key + 50));
      Eigen::Isometry3d E = Eigen::Isometry3d::Identity();
      E.linear() = Eigen::AngleAxisd(dr.norm() * o.pose_noise_deg * M_PI / 180.0, dr.normalized()).toRotationMatrix();
      E.translation() = o.pose_noise_m * dt;
      T = T * E;
    }
    s.T_ref_camera.push_back(T);
  }
  const Eigen::Isometry3d& T_cam_world = T_ref_world;
  s.gravity_camera = T_cam_world.linear() * Eigen::Vector3d(0, 0, -1);
  for (const auto& t : s.truss.tomatoes) {
    TruthTomato x;
    x.centre_m = T_cam_world * t.centre_m;
    x.radius_m = t.radius_m;
    x.pedicel_dir = T_cam_world.linear() * t.pedicel_dir;
    x.pedicel_force_n = T_cam_world.linear() * t.pedicel_force_n;
    std::vector<std::uint8_t> mine(s.world.size(), 0);
    for (std::size_t k = 0; k < s.world.size(); ++k)
      mine[k] = s.world.object(static_cast<sim::ObjectId>(k)).name.rfind(t.object_name, 0) == 0;
    for (std::size_t v = 0; v < s.frames.size(); ++v) {
      int n = 0;
      for (auto id : s.frames[v].object) n += id != sim::kNoObject && mine[static_cast<std::size_t>(id)];
      if (v == 0) x.visible_pixels = n;
      x.visible_pixels_any = std::max(x.visible_pixels_any, n);
    }
    s.truth.push_back(x);
  }
  for (const auto& c : s.truss.contacts) {
    if (c.kind != sim::ContactKind::kFruit) continue;
    s.contacts.emplace_back(c.i, c.j);
    ++s.truth[static_cast<std::size_t>(c.i)].edges;
    ++s.truth[static_cast<std::size_t>(c.j)].edges;
  }
  for (const auto& d : second) s.distractors.push_back(T_cam_world * d.centre_m);
  return s;
}

ColorCloud render_again(const Scenario& s, const ScenarioOptions& o, std::size_t view, std::uint64_t frame_index) {
  const sim::RgbdFrame f = sim::RgbdCamera(o.camera).render(s.world, s.frames.at(view).T_world_camera, frame_index);
  ColorCloud c = to_cloud(f);
  apply_conditions(o, s.world, f, splitmix64(frame_index * 104729 + view) << 20, c);
  return c;
}

}  // namespace tinyline::tomato_reasoning::eval
