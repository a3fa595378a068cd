// SPDX-License-Identifier: Apache-2.0
// What the circle fits' sources share (not installed): the points'
// normalisation and checks, the algebraic circle, and the second-order
// correction's steps the geometric fit calls.
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "hydrus_fitting/circle_fit.hpp"

namespace tinyline::hydrus_fitting::detail {

// Beyond this radius, in units of the points' RMS spread, a circle is a line
// for every practical purpose (and the algebraic solution is rounding noise).
constexpr double kLineRadiusRatio = 1e8;
// Points whose scatter has a smallest/largest eigenvalue ratio below this are
// a line: the eigenvalues carry ~1e-16 relative rounding, so anything much
// smaller cannot be told from zero (a 1 m line with 1 um of wiggle is a line).
constexpr double kCollinearPlanarity = 1e-12;

inline CircleFit failed(FitStatus s, std::string reason, int non_finite = 0) {
  CircleFit f;
  f.set_outcome(s, std::move(reason));
  f.non_finite = non_finite;
  return f;
}

inline bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

/// The finite points, centred on their mean and scaled to unit RMS distance,
/// so the algebraic fits' moment matrices are well conditioned.
struct Normalised {
  Eigen::Matrix2Xd q;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double scale = 1.0;  // q = (p - mean) / scale
  int non_finite = 0;
};

/// Centres n.q (filled with finite points) on its mean, scales it to unit RMS distance.
inline void centre_and_scale(Normalised& n) {
  const auto k = n.q.cols();
  if (k == 0) return;
  n.mean = n.q.rowwise().mean();
  n.q.colwise() -= n.mean;
  const double ms = n.q.squaredNorm() / static_cast<double>(k);
  n.scale = ms > 0.0 ? std::sqrt(ms) : 1.0;
  n.q /= n.scale;
}

inline Normalised normalise(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  Normalised n;
  n.q.resize(2, points.cols());
  Eigen::Index k = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (finite(points.col(i))) {
      n.q.col(k++) = points.col(i);
    } else {
      ++n.non_finite;
    }
  }
  n.q.conservativeResize(2, k);
  centre_and_scale(n);
  return n;
}

/// Smallest over largest eigenvalue of the (normalised) scatter matrix: 0 for
/// points on a line, 1 for an isotropic spread.
inline double planarity(const Eigen::Matrix2Xd& q) {
  // Three sums: q q^T as a general product goes through the blocked GEMM
  // kernel, which costs more than the sums for a 2 x n matrix.
  Eigen::Matrix2d s;
  s(0, 0) = q.row(0).squaredNorm();
  s(1, 1) = q.row(1).squaredNorm();
  s(0, 1) = s(1, 0) = q.row(0).dot(q.row(1));
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(s, Eigen::EigenvaluesOnly);
  const double hi = es.eigenvalues()(1);
  return hi > 0.0 ? es.eigenvalues()(0) / hi : 0.0;
}

inline double rms_distance(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const Circle& c) {
  double s = 0.0;
  int n = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (!finite(points.col(i))) continue;
    const double d = (points.col(i) - c.centre_m).norm() - c.radius_m;
    s += d * d;
    ++n;
  }
  return n > 0 ? std::sqrt(s / n) : 0.0;
}

/// Circle from the algebraic parameters A (A0 z + A1 x + A2 y + A3 = 0) in
/// normalised coordinates, mapped back. Fails on a line (A0 ~ 0).
inline std::optional<Circle> circle_from_algebraic(const Eigen::Vector4d& A, const Normalised& n) {
  const double disc = A(1) * A(1) + A(2) * A(2) - 4.0 * A(0) * A(3);
  const double r_norm = std::sqrt(std::max(disc, 0.0)) / (2.0 * std::abs(A(0)));
  if (!std::isfinite(r_norm) || r_norm > kLineRadiusRatio || disc <= 0.0) return std::nullopt;
  return Circle{n.mean + n.scale * Eigen::Vector2d(-A(1) / (2.0 * A(0)), -A(2) / (2.0 * A(0))), n.scale * r_norm};
}

/// The same as a fit result, with the RMS distance of `points`.
inline CircleFit from_algebraic(const Eigen::Vector4d& A, const Normalised& n,
                                const Eigen::Ref<const Eigen::Matrix2Xd>& points, const char* method) {
  const auto circle = circle_from_algebraic(A, n);
  if (!circle) {
    return failed(FitStatus::kCollinear,
                  fmt::format("{} fit: the {} points are collinear (no finite circle fits them)", method, n.q.cols()),
                  n.non_finite);
  }
  CircleFit f;
  f.set_outcome(FitStatus::kOk);
  f.circle = *circle;
  f.points_used = static_cast<int>(n.q.cols());
  f.non_finite = n.non_finite;
  f.rms_residual_m = rms_distance(points, f.circle);
  return f;
}

/// Common checks of the algebraic fits: enough finite points, not all on a line.
inline std::optional<CircleFit> check_algebraic_input(const Normalised& n, const char* method) {
  const auto k = n.q.cols();
  if (k < 3) {
    return failed(FitStatus::kTooFewPoints,
                  fmt::format("{} fit needs at least 3 finite points, got {}{}", method, k,
                              n.non_finite ? fmt::format(" ({} non-finite skipped)", n.non_finite) : ""),
                  n.non_finite);
  }
  if (planarity(n.q) < kCollinearPlanarity) {
    return failed(FitStatus::kCollinear, fmt::format("{} fit: the {} points are collinear", method, k), n.non_finite);
  }
  return std::nullopt;
}

/// The Hyper fit's algebraic parameters for checked, normalised points.
Eigen::Vector4d hyper_parameters(const Normalised& n);

common::Status validate_second_order(const SecondOrderCorrection& so);

/// Step 1 of the second-order correction, the weights: multiplies the n
/// points' weights `pw` by the arc's end weights for the noise over the
/// radius q seen in the residuals of `f`; returns the end weight applied
/// (0: none, the weights unchanged, no refit needed).
double weight_the_arc_ends(const CircleFit& f, const double* px, const double* py, double* pw, int n, double q,
                           const SecondOrderCorrection& so);

/// Step 2: theta -= gamma Cov(theta, r) / r, the shift of r capped.
void shift_to_the_mode(CircleFit& f, const SecondOrderCorrection& so);

}  // namespace tinyline::hydrus_fitting::detail
