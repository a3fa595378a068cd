// SPDX-License-Identifier: Apache-2.0
#include "planar_scene.hpp"

#include <cmath>
#include <limits>

namespace tinyline::hydrus_fitting::eval {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// What a ray hits first: its distance, kind and index.
struct Hit {
  double t = kInf;
  int kind = kHitNone, index = -1;

  void offer(double t_hit, int hit_kind, std::size_t hit_index) {
    if (t_hit < t) {
      t = t_hit;
      kind = hit_kind;
      index = static_cast<int>(hit_index);
    }
  }
};

/// The first hit of the ray from `o` along `d`. Shapes that contain the
/// origin are skipped (a sensor sits on its own link; light leaves it).
Hit first_hit(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const PlanarWorld& world,
              const std::vector<Capsule>& links) {
  Hit h;
  for (std::size_t c = 0; c < world.cylinders.size(); ++c) {
    const Circle& cyl = world.cylinders[c];
    if ((o - cyl.centre_m).norm() >= cyl.radius_m)
      h.offer(ray_circle(o, d, cyl.centre_m, cyl.radius_m), kHitCylinder, c);
  }
  for (std::size_t c = 0; c < world.obstacles.size(); ++c)
    if (!inside_capsule(o, world.obstacles[c])) h.offer(ray_capsule(o, d, world.obstacles[c]), kHitObstacle, c);
  if (world.robot_links_visible)
    for (std::size_t c = 0; c < links.size(); ++c)
      if (!inside_capsule(o, links[c])) h.offer(ray_capsule(o, d, links[c]), kHitRobot, c);
  return h;
}

}  // namespace

std::vector<double> pixel_angles(const SensorSpec& s, int pixels) {
  std::vector<double> a(static_cast<std::size_t>(pixels));
  for (int i = 0; i < pixels; ++i) {
    const double u_mm = (i + 0.5 - 0.5 * pixels) * s.sensor_length_mm / pixels;
    a[static_cast<std::size_t>(i)] = std::atan(u_mm / s.focal_mm);
  }
  return a;
}

std::vector<SyntheticScan> scan_all(const RobotModel& model, const std::vector<double>& q, const PlanarWorld& world,
                                    const SyntheticScanParams& params, common::SplitMixRandom& rng) {
  const Kinematics k = model.forward(q);
  const auto links = link_capsules(model, k);
  std::vector<SyntheticScan> out;
  for (std::size_t si = 0; si < model.sensors().size(); ++si) {
    const SensorSpec& spec = model.sensors()[si];
    const auto& T = k.T_base_sensor[si];
    SyntheticScan s;
    s.sensor = spec.name;
    s.angle_rad = pixel_angles(spec, params.pixels);
    for (const double a : s.angle_rad) {
      const Eigen::Vector2d d = (T.linear() * spec.ray(a)).normalized();
      const Hit h = first_hit(T.translation(), d, world, links);
      const double best = h.t;
      if (!(best <= spec.max_range_m)) {
        s.range_m.push_back(std::numeric_limits<double>::quiet_NaN());
        s.true_range_m.push_back(std::numeric_limits<double>::quiet_NaN());
        s.hit_kind.push_back(kHitNone);
        s.hit_index.push_back(-1);
        continue;
      }
      s.true_range_m.push_back(best);
      s.range_m.push_back(best + params.noise_scale * params.noise.sd_at(best) * rng.normal());
      s.hit_kind.push_back(h.kind);
      s.hit_index.push_back(h.index);
    }
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace tinyline::hydrus_fitting::eval
