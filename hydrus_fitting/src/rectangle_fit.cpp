// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/rectangle_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include <tinyline/common/random.hpp>

namespace tinyline::hydrus_fitting {

namespace {

Eigen::Vector2d perp(const Eigen::Vector2d& u) { return {-u.y(), u.x()}; }

/// Total least squares line through points: direction (unit) and centroid.
bool fit_line(const std::vector<Eigen::Vector2d>& p, Eigen::Vector2d& dir, Eigen::Vector2d& centroid) {
  if (p.size() < 2) return false;
  centroid.setZero();
  for (const auto& x : p) centroid += x;
  centroid /= static_cast<double>(p.size());
  Eigen::Matrix2d C = Eigen::Matrix2d::Zero();
  for (const auto& x : p) C.noalias() += (x - centroid) * (x - centroid).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(C);
  dir = es.eigenvectors().col(1);
  return es.eigenvalues()(1) > 0.0;
}

}  // namespace

common::Status validate(const RectangleFitParams& params) {
  if (!(params.inlier_threshold_m > 0.0)) return common::Status::invalid("inlier_threshold_m must be > 0");
  if (params.min_points_per_side < 2) return common::Status::invalid("min_points_per_side must be >= 2");
  if (!(params.confidence > 0.0 && params.confidence < 1.0))
    return common::Status::invalid("confidence must be in (0, 1)");
  if (params.known_size_m && !(params.known_size_m->array() > 0.0).all())
    return common::Status::invalid("known_size_m must be > 0");
  return common::Status{};
}

namespace {

/// fit_rectangle's steps on one input: the finite points, the first side by
/// MSAC, the second side perpendicular to it near one of its ends, both
/// refined with one shared orientation, then the corner, extent, size and
/// centre. `out` collects the result as the steps go.
struct RectangleFitter {
  RectangleFitter(const Eigen::Ref<const Eigen::Matrix2Xd>& p, const RectangleFitParams& prm, const Viewpoints& v)
      : points(p), params(prm), viewpoints(v) {}

  const Eigen::Ref<const Eigen::Matrix2Xd>& points;
  const RectangleFitParams& params;
  const Viewpoints& viewpoints;
  RectangleFit out;
  std::vector<int> idx;  ///< finite points
  double T = 0.0, T2 = 0.0;
  // The sides: direction u1 of side 1, its normal n1 (side 2's direction),
  // side 1 on n1.p = d1, side 2 on u1.p = d2.
  Eigen::Vector2d u1 = Eigen::Vector2d::UnitX(), n1 = Eigen::Vector2d::UnitY(), c1 = Eigen::Vector2d::Zero();
  double d1 = 0.0, d2 = 0.0;
  bool two = false;    ///< a second side was found
  bool have2 = false;  ///< ... and kept its support through the refinement
  std::vector<Eigen::Vector2d> s1, s2;
  std::vector<int> rest;        ///< finite points off side 1 after its refit
  double lo1 = 0.0, hi1 = 0.0;  ///< side 1's extent along u1

  RectangleFit fail(FitStatus s, std::string r) {
    out.set_outcome(s, std::move(r));
    return out;
  }

  /// The finite points; false when there are too few for a side.
  bool finite_points() {
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      if (std::isfinite(points(0, i)) && std::isfinite(points(1, i))) {
        idx.push_back(static_cast<int>(i));
      } else {
        ++out.non_finite;
      }
    }
    out.side_of_point.assign(static_cast<std::size_t>(points.cols()), 0);
    T = params.inlier_threshold_m;
    T2 = T * T;
    return static_cast<int>(idx.size()) >= params.min_points_per_side;
  }

  /// Side 1: MSAC over 2-point lines; the best line's inlier count.
  int msac_side1() {
    const int n = static_cast<int>(idx.size());
    common::SplitMixRandom rng(params.seed);
    double best_score = std::numeric_limits<double>::infinity();
    int best_in = 0;
    long long needed = params.max_iterations;
    for (int it = 0; it < needed && it < params.max_iterations; ++it) {
      const int a = idx[rng.below(static_cast<std::uint64_t>(n))];
      const int b = idx[rng.below(static_cast<std::uint64_t>(n))];
      const Eigen::Vector2d d = points.col(b) - points.col(a);
      if (a == b || d.norm() < 1e-9) continue;
      const Eigen::Vector2d u = d.normalized(), nn = perp(u), c = points.col(a);
      double sc = 0.0;
      int in = 0;
      for (const int i : idx) {
        const double r = nn.dot(points.col(i) - c);
        if (r * r < T2) {
          sc += r * r;
          ++in;
        } else {
          sc += T2;
        }
        if (sc > best_score) break;
      }
      if (sc < best_score) {
        best_score = sc;
        u1 = u;
        c1 = c;
        best_in = in;
        const double pin = std::pow(static_cast<double>(in) / n, 2);
        if (pin >= 1.0) {
          needed = 0;
        } else if (pin > 0.0) {
          needed = std::min<long long>(
              params.max_iterations,
              static_cast<long long>(std::ceil(std::log(1.0 - params.confidence) / std::log1p(-pin))));
        }
      }
    }
    return best_in;
  }

  /// The points within T of the line (u, c) into dst, the others into *rest.
  void collect_line(const Eigen::Vector2d& u, const Eigen::Vector2d& c, std::vector<Eigen::Vector2d>& dst,
                    std::vector<int>* others) const {
    dst.clear();
    if (others) others->clear();
    const Eigen::Vector2d nn = perp(u);
    for (const int i : idx) {
      if (std::abs(nn.dot(points.col(i) - c)) < T) {
        dst.push_back(points.col(i));
      } else if (others) {
        others->push_back(i);
      }
    }
  }

  /// Side 1 alone refitted (TLS on its inliers) before looking for side 2.
  void refine_side1() {
    for (int r = 0; r < 2; ++r) {
      collect_line(u1, c1, s1, nullptr);
      Eigen::Vector2d u, c;
      if (fit_line(s1, u, c)) {
        u1 = u;
        c1 = c;
      }
    }
    collect_line(u1, c1, s1, &rest);
  }

  /// Side 2: perpendicular to side 1, its line through a remaining point
  /// near an end of side 1 (MSAC over those).
  void find_side2() {
    n1 = perp(u1);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& p : s1) {
      lo = std::min(lo, u1.dot(p));
      hi = std::max(hi, u1.dot(p));
    }
    double best2 = std::numeric_limits<double>::infinity();
    int in2_best = 0;
    for (const int i : rest) {
      const double t = u1.dot(points.col(i));
      if (std::min(std::abs(t - lo), std::abs(t - hi)) > params.max_corner_gap_m + T) continue;
      double sc = 0.0;
      int in = 0;
      for (const int k : rest) {
        const double r = u1.dot(points.col(k)) - t;
        if (r * r < T2) {
          sc += r * r;
          ++in;
        } else {
          sc += T2;
        }
        if (sc > best2) break;
      }
      if (sc < best2) {
        best2 = sc;
        d2 = t;
        in2_best = in;
      }
    }
    two = in2_best >= params.min_points_per_side;
    d1 = n1.dot(c1);
  }

  /// Each finite point to side 1, side 2 or neither; a side only on its own
  /// half-line from the corner (up to the tolerance) after the first round.
  void assign_sides(int round, double sgn1, double sgn2) {
    s1.clear();
    s2.clear();
    std::fill(out.side_of_point.begin(), out.side_of_point.end(), 0);
    for (const int i : idx) {
      const Eigen::Vector2d p = points.col(i);
      const double r1 = n1.dot(p) - d1;
      const double r2 = u1.dot(p) - d2;
      const bool on1 = std::abs(r1) < T && (!two || round == 0 || sgn1 * r2 > -T);
      const bool on2 = two && std::abs(r2) < T && (round == 0 || sgn2 * r1 > -T);
      if (on1 && (!on2 || std::abs(r1) <= std::abs(r2))) {
        s1.push_back(p);
        out.side_of_point[static_cast<std::size_t>(i)] = 1;
      } else if (on2) {
        s2.push_back(p);
        out.side_of_point[static_cast<std::size_t>(i)] = 2;
      }
    }
  }

  /// Both sides refitted with one orientation; false when side 1 lost its support.
  bool joint_refinement() {
    double sgn1 = 1.0, sgn2 = 1.0;  // which way each side runs from the corner
    for (int round = 0; round < std::max(1, params.refine_rounds); ++round) {
      assign_sides(round, sgn1, sgn2);
      if (static_cast<int>(s1.size()) < params.min_points_per_side) break;
      Eigen::Vector2d m1 = Eigen::Vector2d::Zero(), m2 = Eigen::Vector2d::Zero();
      for (const auto& p : s1) m1 += p;
      m1 /= static_cast<double>(s1.size());
      Eigen::Matrix2d C1 = Eigen::Matrix2d::Zero(), C2 = Eigen::Matrix2d::Zero();
      for (const auto& p : s1) C1.noalias() += (p - m1) * (p - m1).transpose();
      const bool with2 = two && static_cast<int>(s2.size()) >= params.min_points_per_side;
      if (with2) {
        for (const auto& p : s2) m2 += p;
        m2 /= static_cast<double>(s2.size());
        for (const auto& p : s2) C2.noalias() += (p - m2) * (p - m2).transpose();
      }
      // Side-1 residual n.(p - m1) with n = J u; side-2 residual u.(p - m2):
      // minimise u^T (J^T C1 J + C2) u.
      Eigen::Matrix2d J;
      J << 0, -1, 1, 0;
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(J.transpose() * C1 * J + C2);
      Eigen::Vector2d u = es.eigenvectors().col(0);
      if (u.dot(u1) < 0.0) u = -u;
      u1 = u;
      n1 = perp(u1);
      d1 = n1.dot(m1);
      if (with2) d2 = u1.dot(m2);
      // Directions of the sides away from the corner.
      double a1 = 0.0, a2 = 0.0;
      for (const auto& p : s1) a1 += u1.dot(p) - d2;
      for (const auto& p : s2) a2 += n1.dot(p) - d1;
      sgn1 = a1 >= 0.0 ? 1.0 : -1.0;
      sgn2 = a2 >= 0.0 ? 1.0 : -1.0;
    }
    if (static_cast<int>(s1.size()) < params.min_points_per_side) return false;
    have2 = two && static_cast<int>(s2.size()) >= params.min_points_per_side;
    out.sides_visible = have2 ? 2 : 1;
    return true;
  }

  /// Yaw of u1 in (-pi/2, pi/2]; the corner, the sides' extents and the residual.
  void corner_and_extent() {
    double yaw = std::atan2(u1.y(), u1.x());
    if (yaw <= -std::numbers::pi / 2 || yaw > std::numbers::pi / 2) {
      u1 = -u1;
      n1 = -n1;
      d1 = -d1;
      d2 = -d2;
      yaw = std::atan2(u1.y(), u1.x());
    }
    out.yaw_rad = yaw;
    out.u1 = u1;
    out.u2 = n1;
    lo1 = std::numeric_limits<double>::infinity();
    hi1 = -lo1;
    for (const auto& p : s1) {
      lo1 = std::min(lo1, u1.dot(p));
      hi1 = std::max(hi1, u1.dot(p));
    }
    double rss = 0.0;
    for (const auto& p : s1) rss += std::pow(n1.dot(p) - d1, 2);
    if (have2) {
      out.corner_m = d1 * n1 + d2 * u1;
      const double far1 = std::abs(lo1 - d2) > std::abs(hi1 - d2) ? lo1 : hi1;
      double lo2 = std::numeric_limits<double>::infinity(), hi2 = -lo2;
      for (const auto& p : s2) {
        lo2 = std::min(lo2, n1.dot(p));
        hi2 = std::max(hi2, n1.dot(p));
        rss += std::pow(u1.dot(p) - d2, 2);
      }
      const double far2 = std::abs(lo2 - d1) > std::abs(hi2 - d1) ? lo2 : hi2;
      out.extent_m = {far1 - d2, far2 - d1};
    } else {
      out.corner_m = d1 * n1 + lo1 * u1;
      out.extent_m = {hi1 - lo1, 0.0};
    }
    out.points_side1 = static_cast<int>(s1.size());
    out.points_side2 = have2 ? static_cast<int>(s2.size()) : 0;
    if (!have2) {
      for (auto& s : out.side_of_point)
        if (s == 2) s = 0;
    }
    out.points_used = out.points_side1 + out.points_side2;
    out.rms_residual_m = std::sqrt(rss / out.points_used);
  }

  /// The size (known, or the visible extent) and the centre: from the corner
  /// with two sides; with one side and a known size, on the far side of it
  /// from the sensors.
  void size_and_centre() {
    const Eigen::Vector2d e = out.extent_m.cwiseAbs();
    if (params.known_size_m) {
      Eigen::Vector2d sz = *params.known_size_m;
      // Put the longer known side along the longer visible extent.
      if ((e.x() >= e.y()) != (sz.x() >= sz.y())) std::swap(sz.x(), sz.y());
      out.size_m = sz;
    } else {
      out.size_m = e;
    }
    const double s1sign = out.extent_m.x() >= 0.0 ? 1.0 : -1.0;
    if (have2) {
      const double s2sign = out.extent_m.y() >= 0.0 ? 1.0 : -1.0;
      out.centre_m = out.corner_m + 0.5 * s1sign * out.size_m.x() * u1 + 0.5 * s2sign * out.size_m.y() * n1;
    } else if (params.known_size_m && !viewpoints.origins_m.empty()) {
      double toward = 0.0;
      for (const int i : idx) {
        if (out.side_of_point[static_cast<std::size_t>(i)] != 1) continue;
        const auto& o =
            viewpoints.origins_m[static_cast<std::size_t>(viewpoints.sensor_of_point[static_cast<std::size_t>(i)])];
        toward += n1.dot(o - points.col(i));
      }
      const double away = toward > 0.0 ? -1.0 : 1.0;
      out.centre_m = out.corner_m + 0.5 * (hi1 - lo1) * u1 + away * 0.5 * out.size_m.y() * n1;
    }
  }
};

}  // namespace

RectangleFit fit_rectangle(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const RectangleFitParams& params,
                           const Viewpoints& viewpoints) {
  RectangleFitter f(points, params, viewpoints);
  if (const common::Status v = validate(params); !v.ok()) return f.fail(FitStatus::kInvalidParams, v.message);
  if (!viewpoints.origins_m.empty() && viewpoints.sensor_of_point.size() != static_cast<std::size_t>(points.cols()))
    return f.fail(FitStatus::kInvalidParams, "viewpoints.sensor_of_point must have one entry per point");
  if (!f.finite_points()) {
    return f.fail(FitStatus::kTooFewPoints, fmt::format("rectangle fit needs at least {} finite points, got {}",
                                                        params.min_points_per_side, f.idx.size()));
  }
  if (f.msac_side1() < params.min_points_per_side) {
    return f.fail(FitStatus::kNoConsensus, fmt::format("no line with {} or more of the {} points within {} m",
                                                       params.min_points_per_side, f.idx.size(), f.T));
  }
  f.refine_side1();
  f.find_side2();
  if (!f.joint_refinement()) return f.fail(FitStatus::kNoConsensus, "the first side lost its support while refining");
  f.corner_and_extent();
  f.size_and_centre();
  f.out.set_outcome(FitStatus::kOk);
  return f.out;
}

}  // namespace tinyline::hydrus_fitting
