// SPDX-License-Identifier: Apache-2.0
#include "planar_scene.hpp"

#include <cmath>
#include <limits>

namespace tinyline::hydrus_fitting::eval {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double ray_circle(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& c, double r) {
  const Eigen::Vector2d oc = o - c;
  const double b = oc.dot(d);
  const double disc = b * b - (oc.squaredNorm() - r * r);
  if (disc < 0.0) return kInf;
  const double s = std::sqrt(disc);
  if (-b - s > 1e-9) return -b - s;
  return kInf;  // origin inside or behind: no front face
}

double ray_segment(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& p,
                   const Eigen::Vector2d& q) {
  const Eigen::Vector2d e = q - p;
  const double den = d.x() * e.y() - d.y() * e.x();
  if (std::abs(den) < 1e-15) return kInf;
  const Eigen::Vector2d w = p - o;
  const double t = (w.x() * e.y() - w.y() * e.x()) / den;
  const double u = (w.x() * d.y() - w.y() * d.x()) / den;
  return (t > 1e-9 && u >= 0.0 && u <= 1.0) ? t : kInf;
}

double ray_capsule(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Capsule& c) {
  // Skip a capsule the ray starts in (the sensor's own link).
  const Eigen::Vector2d ab = c.b_m - c.a_m;
  const double l2 = ab.squaredNorm();
  const double t0 = l2 > 0 ? std::clamp((o - c.a_m).dot(ab) / l2, 0.0, 1.0) : 0.0;
  if ((c.a_m + t0 * ab - o).norm() < c.half_width_m) return kInf;
  double t = std::min(ray_circle(o, d, c.a_m, c.half_width_m), ray_circle(o, d, c.b_m, c.half_width_m));
  const double len = std::sqrt(l2);
  if (len > 0.0) {
    const Eigen::Vector2d n = Eigen::Vector2d(-ab.y(), ab.x()) / len * c.half_width_m;
    t = std::min(t, ray_segment(o, d, c.a_m + n, c.b_m + n));
    t = std::min(t, ray_segment(o, d, c.a_m - n, c.b_m - n));
  }
  return t;
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
      const Eigen::Vector2d o = T.translation();
      double best = kInf;
      int kind = kHitNone, index = -1;
      for (std::size_t c = 0; c < world.cylinders.size(); ++c) {
        const double t = ray_circle(o, d, world.cylinders[c].centre_m, world.cylinders[c].radius_m);
        if (t < best) {
          best = t;
          kind = kHitCylinder;
          index = static_cast<int>(c);
        }
      }
      for (std::size_t c = 0; c < world.obstacles.size(); ++c) {
        const double t = ray_capsule(o, d, world.obstacles[c]);
        if (t < best) {
          best = t;
          kind = kHitObstacle;
          index = static_cast<int>(c);
        }
      }
      if (world.robot_links_visible) {
        for (std::size_t c = 0; c < links.size(); ++c) {
          const double t = ray_capsule(o, d, links[c]);
          if (t < best) {
            best = t;
            kind = kHitRobot;
            index = static_cast<int>(c);
          }
        }
      }
      if (!(best <= spec.max_range_m)) {
        s.range_m.push_back(std::numeric_limits<double>::quiet_NaN());
        s.true_range_m.push_back(std::numeric_limits<double>::quiet_NaN());
        s.hit_kind.push_back(kHitNone);
        s.hit_index.push_back(-1);
        continue;
      }
      s.true_range_m.push_back(best);
      s.range_m.push_back(best + params.noise_scale * params.noise.sd_at(best) * rng.normal());
      s.hit_kind.push_back(kind);
      s.hit_index.push_back(index);
    }
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace tinyline::hydrus_fitting::eval
