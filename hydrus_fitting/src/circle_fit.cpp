// SPDX-License-Identifier: Apache-2.0
// The circle fits' vocabulary (statuses, corrections) and the KCR bound
// they are measured against; the fits live in circle_fit_{algebraic,
// geometric,second_order,robust}.cpp.
#include "hydrus_fitting/circle_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <fmt/format.h>

#include <tinyline/common/least_squares.hpp>
#include <tinyline/common/random.hpp>

#include "circle_fit_internal.hpp"

namespace tinyline::hydrus_fitting {

using namespace detail;

const char* to_string(FitStatus s) {
  switch (s) {
    case FitStatus::kOk: return "ok";
    case FitStatus::kTooFewPoints: return "too_few_points";
    case FitStatus::kCollinear: return "collinear";
    case FitStatus::kNoConsensus: return "no_consensus";
    case FitStatus::kRadiusOutOfRange: return "radius_out_of_range";
    case FitStatus::kInvalidParams: return "invalid_params";
  }
  return "unknown";
}

common::Status fit_status(FitStatus detail, std::string message) {
  switch (detail) {
    case FitStatus::kOk: return {};
    case FitStatus::kInvalidParams: return common::Status::invalid(std::move(message));
    case FitStatus::kTooFewPoints:
    case FitStatus::kCollinear:
    case FitStatus::kNoConsensus:
    case FitStatus::kRadiusOutOfRange: break;
  }
  return common::Status::not_found(std::move(message));
}

const char* to_string(ArcCorrection c) {
  switch (c) {
    case ArcCorrection::kNone: return "none";
    case ArcCorrection::kSecondOrder: return "second_order";
  }
  return "unknown";
}

KcrBound kcr_bound(const Eigen::Ref<const Eigen::Matrix2Xd>& true_points, const Circle& truth,
                   std::span<const double> sigma_m, bool known_radius) {
  KcrBound b;
  const auto n = true_points.cols();
  if (sigma_m.size() != 1 && sigma_m.size() != static_cast<std::size_t>(n)) {
    b.status = common::Status::invalid(fmt::format("sigma_m needs 1 or {} entries, got {}", n, sigma_m.size()));
    return b;
  }
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const double s = sigma_m.size() == 1 ? sigma_m[0] : sigma_m[static_cast<std::size_t>(i)];
    if (!(s > 0.0) || !std::isfinite(s) || !finite(true_points.col(i))) {
      b.status = common::Status::invalid(fmt::format("point {} has a non-finite coordinate or sigma {}", i, s));
      return b;
    }
    const Eigen::Vector2d dv = true_points.col(i) - truth.centre_m;
    const double rho = dv.norm();
    if (rho == 0.0) {
      b.status = common::Status::invalid(fmt::format("point {} is at the centre", i));
      return b;
    }
    const Eigen::Vector3d g(-dv.x() / rho, -dv.y() / rho, -1.0);
    W.noalias() += g * g.transpose() / (s * s);
  }
  if (known_radius) {
    Eigen::FullPivLU<Eigen::Matrix2d> lu(W.topLeftCorner<2, 2>());
    if (!lu.isInvertible()) {
      b.status = common::Status::invalid("information matrix is singular (fewer than 2 distinct directions)");
      return b;
    }
    b.covariance.topLeftCorner<2, 2>() = lu.inverse();
  } else {
    Eigen::FullPivLU<Eigen::Matrix3d> lu(W);
    if (!lu.isInvertible() || n < 3) {
      b.status = common::Status::invalid("information matrix is singular (fewer than 3 distinct directions)");
      return b;
    }
    b.covariance = lu.inverse();
  }
  return b;
}

}  // namespace tinyline::hydrus_fitting
