// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/tomato_registration.hpp"

#include "laser_clustering/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include <Eigen/LU>
#include <fmt/format.h>

namespace tinyline::laser_clustering {

common::Status validate(const TomatoRegistrationParams& p) {
  // The single fields' ranges are the table's; these two span fields.
  if (common::Status v = common::within_table(p); !v.ok()) return v;
  if (p.grid_step_m > p.max_shift_m) {
    return common::Status::invalid(
        fmt::format("grid_step_m must be in (0, max_shift_m] (got {} and {})", p.grid_step_m, p.max_shift_m));
  }
  if (p.max_range_m <= p.min_range_m) {
    return common::Status::invalid(
        fmt::format("need 0 <= min_range_m < max_range_m (got {} and {})", p.min_range_m, p.max_range_m));
  }
  return {};
}

namespace {

struct Section {
  Eigen::Vector2d centre;  // in the plane (x, z)
  double radius;
};

// The nearest shifted near arc to p: its index and the signed radial
// residual |p - c| - r; index -1 when p lies on no circle's near half.
struct Nearest {
  int section = -1;
  double residual = 0.0;
  Eigen::Vector2d v = Eigen::Vector2d::Zero();  // p - shifted centre
};

Nearest nearest_arc(const Eigen::Vector2d& p, const std::vector<Section>& sections, const Eigen::Vector2d& shift) {
  Nearest best;
  double best_abs = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < sections.size(); ++i) {
    const Eigen::Vector2d c = sections[i].centre + shift;
    const Eigen::Vector2d v = p - c;
    if (v.dot(c) >= 0.0) continue;  // the far half: the sensor cannot see it
    const double r = v.norm() - sections[i].radius;
    if (std::abs(r) < best_abs) {
      best_abs = std::abs(r);
      best = {static_cast<int>(i), r, v};
    }
  }
  return best;
}

struct Ray {
  Eigen::Vector2d u;  // unit direction (x, z)
  double angle;       // its bearing [rad], ascending over rays
  double range;       // measured; NaN: no return
};

struct Point {
  Eigen::Vector2d p;
  double angle;  // ascending over points
};

// The index range of `v` (ascending by .angle) with bearings within
// half_width of bearing.
template <class T>
std::pair<std::size_t, std::size_t> window(const std::vector<T>& v, double bearing, double half_width) {
  auto by_angle = [](const T& a, double b) { return a.angle < b; };
  const auto lo = std::lower_bound(v.begin(), v.end(), bearing - half_width, by_angle);
  const auto hi = std::lower_bound(lo, v.end(), bearing + half_width, by_angle);
  return {static_cast<std::size_t>(lo - v.begin()), static_cast<std::size_t>(hi - v.begin())};
}

double half_angle(double radius, double distance) {
  return radius >= distance ? std::numbers::pi : std::asin(radius / distance);
}

// Pixels that see through a shifted cross-section's middle (within
// core_fraction of its radius from the centre): the return (or its
// absence) lies more than the margin behind the near arc.
double violations(const std::vector<Ray>& rays, const std::vector<Section>& sections, const Eigen::Vector2d& shift,
                  const TomatoRegistrationParams& p, int* count = nullptr) {
  double cost = 0.0;
  int n = 0;
  for (const Section& sec : sections) {
    const Eigen::Vector2d c = sec.centre + shift;
    const double core = p.core_fraction * sec.radius, cc = c.squaredNorm();
    const auto [lo, hi] = window(rays, std::atan2(c.x(), c.y()), half_angle(core, std::sqrt(cc)));
    for (std::size_t k = lo; k < hi; ++k) {
      const Ray& r = rays[k];
      const double uc = r.u.dot(c);
      if (uc <= 0.0) continue;
      const double off2 = cc - uc * uc;  // squared distance of the centre from the ray
      if (off2 > core * core) continue;
      const double near = uc - std::sqrt(sec.radius * sec.radius - off2);
      if (!std::isfinite(r.range)) {
        cost += p.no_return_cost;
        ++n;
      } else if (r.range > near + p.free_space_margin_m) {
        cost += p.violation_cost;
        ++n;
      }
    }
  }
  if (count) *count = n;
  return cost;
}

// Sum over the returns of 1 - (d / inlier_m)^2 for d the distance to the
// nearest shifted near arc (those within inlier_m), less the free-space
// violations (their count into *violation_count when given). Only returns
// within a section's bearing window can be within inlier_m of it; `best` is
// scratch.
double support(const std::vector<Point>& points, const std::vector<Ray>& rays, const std::vector<Section>& sections,
               const Eigen::Vector2d& shift, const TomatoRegistrationParams& p, std::vector<double>& best,
               int* violation_count = nullptr) {
  best.assign(points.size(), p.inlier_m);
  for (const Section& sec : sections) {
    const Eigen::Vector2d c = sec.centre + shift;
    const auto [lo, hi] = window(points, std::atan2(c.x(), c.y()), half_angle(sec.radius + p.inlier_m, c.norm()));
    for (std::size_t k = lo; k < hi; ++k) {
      const Eigen::Vector2d v = points[k].p - c;
      if (v.dot(c) >= 0.0) continue;  // the far half: the sensor cannot see it
      best[k] = std::min(best[k], std::abs(v.norm() - sec.radius));
    }
  }
  const double inv = 1.0 / (p.inlier_m * p.inlier_m);
  double s = 0.0;
  for (const double d : best) s += 1.0 - d * d * inv;  // 0 for returns on no arc
  return s - violations(rays, sections, shift, p, violation_count);
}

// The tomatoes' cross-sections with the laser plane wider than
// min_section_radius_m, into `sections`; InvalidArgument for a bad tomato.
common::Status plane_sections(std::span<const ExpectedTomato> tomatoes, const TomatoRegistrationParams& p,
                              std::vector<Section>& sections) {
  for (std::size_t i = 0; i < tomatoes.size(); ++i) {
    const ExpectedTomato& t = tomatoes[i];
    if (!t.centre_m.allFinite() || !(std::isfinite(t.radius_m) && t.radius_m > 0.0)) {
      return common::Status::invalid(
          fmt::format("tomato {} needs a finite centre and a radius > 0 (got {})", i, t.radius_m));
    }
    const double h = t.centre_m.y();
    if (std::abs(h) >= t.radius_m) continue;
    const double r = std::sqrt(t.radius_m * t.radius_m - h * h);
    if (r >= p.min_section_radius_m) sections.push_back({Eigen::Vector2d(t.centre_m.x(), t.centre_m.z()), r});
  }
  return {};
}

// Every pixel as a ray, ascending by bearing, and the returns within the
// range limits as points; InvalidArgument for a non-finite or non-monotone angle.
common::Status rays_and_points(const LineScan& scan, const TomatoRegistrationParams& p, std::vector<Ray>& rays,
                               std::vector<Point>& points) {
  const bool descending = scan.size() > 1 && scan.angle_rad.front() > scan.angle_rad.back();
  for (std::size_t k = 0; k < scan.size(); ++k) {
    const std::size_t i = descending ? scan.size() - 1 - k : k;
    const double a = scan.angle_rad[i];
    if (!std::isfinite(a) || (!rays.empty() && !(a > rays.back().angle))) {
      return common::Status::invalid(fmt::format("pixel {} has a non-finite or non-monotone angle ({})", i, a));
    }
    const Eigen::Vector2d u(std::sin(a), std::cos(a));
    rays.push_back({u, a, scan.valid(i) ? scan.range_m[i] : std::numeric_limits<double>::quiet_NaN()});
    if (!scan.valid(i) || scan.range_m[i] < p.min_range_m || scan.range_m[i] > p.max_range_m) continue;
    points.push_back({scan.range_m[i] * u, a});
  }
  return {};
}

// Coarse: every shift on the grid within the disc (the best distinct one
// into out's runner-up); then a grid four times finer around the best
// coarse cell. Returns the best shift.
Eigen::Vector2d grid_search(const std::vector<Point>& points, const std::vector<Ray>& rays,
                            const std::vector<Section>& sections, const TomatoRegistrationParams& p,
                            TomatoRegistration& out) {
  struct Cell {
    Eigen::Vector2d shift;
    double support;
  };
  std::vector<double> scratch;
  std::vector<Cell> cells;
  const int n = static_cast<int>(std::floor(p.max_shift_m / p.grid_step_m));
  for (int ix = -n; ix <= n; ++ix) {
    for (int iz = -n; iz <= n; ++iz) {
      const Eigen::Vector2d s(ix * p.grid_step_m, iz * p.grid_step_m);
      if (s.norm() > p.max_shift_m + 1e-12) continue;
      cells.push_back({s, support(points, rays, sections, s, p, scratch)});
    }
  }
  const auto best =
      std::max_element(cells.begin(), cells.end(), [](const Cell& a, const Cell& b) { return a.support < b.support; });
  for (const Cell& c : cells) {
    if ((c.shift - best->shift).norm() > p.distinct_shift_m && c.support > out.runner_up_support) {
      out.runner_up_support = c.support;
      out.runner_up_shift_xz_m = c.shift;
    }
  }
  Cell fine = *best;
  const double step = p.grid_step_m / 4.0;
  for (int ix = -4; ix <= 4; ++ix) {
    for (int iz = -4; iz <= 4; ++iz) {
      const Eigen::Vector2d s = best->shift + Eigen::Vector2d(ix * step, iz * step);
      const double v = support(points, rays, sections, s, p, scratch);
      if (v > fine.support) fine = {s, v};
    }
  }
  return fine.shift;
}

// Gauss-Newton on the shift, each inlier weighted by Tukey's biweight.
Eigen::Vector2d refine_shift(const std::vector<Point>& points, const std::vector<Section>& sections,
                             Eigen::Vector2d shift, const TomatoRegistrationParams& p) {
  for (int iter = 0; iter < 8; ++iter) {
    Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    for (const auto& q : points) {
      const Nearest nn = nearest_arc(q.p, sections, shift);
      if (nn.section < 0 || std::abs(nn.residual) >= p.inlier_m) continue;
      const double u = nn.residual / p.inlier_m, w = (1.0 - u * u) * (1.0 - u * u);
      const Eigen::Vector2d J = -nn.v / std::max(nn.v.norm(), 1e-9);  // d residual / d shift
      A += w * J * J.transpose();
      b -= w * J * nn.residual;
    }
    if (A.determinant() <= 1e-12) break;
    const Eigen::Vector2d step = A.inverse() * b;  // 2 x 2, determinant checked above
    shift += step;
    if (step.norm() < 1e-6) break;
  }
  return shift;
}

// The fit at `shift`: inliers, their RMS, the support and violations, the
// tomatoes met by at least min_points_per_tomato returns.
void score_shift(const std::vector<Point>& points, const std::vector<Ray>& rays, const std::vector<Section>& sections,
                 const Eigen::Vector2d& shift, const TomatoRegistrationParams& p, TomatoRegistration& out) {
  std::vector<int> per_section(sections.size(), 0);
  double sum2 = 0.0;
  for (const auto& q : points) {
    const Nearest nn = nearest_arc(q.p, sections, shift);
    if (nn.section < 0 || std::abs(nn.residual) >= p.inlier_m) continue;
    ++per_section[static_cast<std::size_t>(nn.section)];
    ++out.inliers;
    sum2 += nn.residual * nn.residual;
  }
  std::vector<double> scratch;
  out.shift_xz_m = shift;
  out.support = support(points, rays, sections, shift, p, scratch, &out.violations);
  out.rms_m = out.inliers ? std::sqrt(sum2 / out.inliers) : 0.0;
  for (const int k : per_section) out.tomatoes_matched += k >= p.min_points_per_tomato;
}

// ok when enough tomatoes are met and no distinct shift comes close (the
// note says how well), else NotFound saying which.
void judge(const TomatoRegistrationParams& p, TomatoRegistration& out) {
  if (out.tomatoes_matched < p.min_tomatoes) {
    out.status = common::Status::not_found(fmt::format("{} of {} tomatoes in the plane met by the scan, need {}",
                                                       out.tomatoes_matched, out.tomatoes_in_plane, p.min_tomatoes));
    return;
  }
  if (out.runner_up_support >= p.ambiguity_ratio * out.support) {
    out.status = common::Status::not_found(
        fmt::format("ambiguous: a shift {:.3f} m away has {:.0f} % of the best's support",
                    (out.runner_up_shift_xz_m - out.shift_xz_m).norm(), 100.0 * out.runner_up_support / out.support));
    return;
  }
  out.note = fmt::format("{} of {} tomatoes matched, {} returns, RMS {:.4f} m, {} pixels see through",
                         out.tomatoes_matched, out.tomatoes_in_plane, out.inliers, out.rms_m, out.violations);
}

}  // namespace

TomatoRegistration register_tomatoes(const LineScan& scan, std::span<const ExpectedTomato> tomatoes,
                                     const TomatoRegistrationParams& p) {
  TomatoRegistration out;
  if (out.status = validate(p); !out.status.ok()) return out;
  if (scan.angle_rad.size() != scan.range_m.size()) {
    out.status = common::Status::invalid(
        fmt::format("scan has {} angles for {} ranges", scan.angle_rad.size(), scan.range_m.size()));
    return out;
  }
  std::vector<Section> sections;
  if (out.status = plane_sections(tomatoes, p, sections); !out.status.ok()) return out;
  out.tomatoes_in_plane = static_cast<int>(sections.size());
  if (sections.empty()) {
    out.status =
        common::Status::not_found(fmt::format("none of the {} tomatoes is cut by the laser plane wider than {:.3f} m",
                                              tomatoes.size(), p.min_section_radius_m));
    return out;
  }
  std::vector<Point> points;
  std::vector<Ray> rays;
  if (out.status = rays_and_points(scan, p, rays, points); !out.status.ok()) return out;
  if (points.empty()) {
    out.status =
        common::Status::not_found(fmt::format("no return between {:.3f} and {:.3f} m", p.min_range_m, p.max_range_m));
    return out;
  }
  const Eigen::Vector2d coarse = grid_search(points, rays, sections, p, out);
  score_shift(points, rays, sections, refine_shift(points, sections, coarse, p), p, out);
  judge(p, out);
  return out;
}

}  // namespace tinyline::laser_clustering
