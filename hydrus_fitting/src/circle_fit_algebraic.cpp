// SPDX-License-Identifier: Apache-2.0
// The algebraic circle fits: Kasa, Hyper, Taubin.
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

CircleFit fit_circle_kasa(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  const Normalised n = normalise(points);
  if (auto bad = check_algebraic_input(n, "Kasa")) return *bad;
  // min sum (z + D x + E y + F)^2: normal equations of [x y 1] against -z.
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n.q.cols(); ++i) {
    const Eigen::Vector3d u(n.q(0, i), n.q(1, i), 1.0);
    M.noalias() += u * u.transpose();
    rhs -= u * n.q.col(i).squaredNorm();
  }
  const Eigen::Vector3d x = M.ldlt().solve(rhs);
  return from_algebraic(Eigen::Vector4d(1.0, x(0), x(1), x(2)), n, points, "Kasa");
}

namespace detail {

Eigen::Vector4d hyper_parameters(const Normalised& n) {
  // Moments of Z = [z x y 1] (data centred, so mean x = mean y = 0): the ten
  // distinct sums of the symmetric u u^T, each added in point order.
  double zz = 0, zx = 0, zy = 0, xx = 0, xy = 0, yy = 0, sx = 0, sy = 0;
  double zbar = 0.0;
  for (Eigen::Index i = 0; i < n.q.cols(); ++i) {
    const double x = n.q(0, i), y = n.q(1, i);
    const double z = n.q.col(i).squaredNorm();
    zz += z * z;
    zx += z * x;
    zy += z * y;
    xx += x * x;
    xy += x * y;
    yy += y * y;
    sx += x;
    sy += y;
    zbar += z;
  }
  Eigen::Matrix4d M;
  M << zz, zx, zy, zbar, zx, xx, xy, sx, zy, xy, yy, sy, zbar, sx, sy, static_cast<double>(n.q.cols());
  const double k = static_cast<double>(n.q.cols());
  M /= k;
  zbar /= k;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(M);
  const Eigen::Vector4d lam = es.eigenvalues().cwiseMax(0.0);
  Eigen::Vector4d A;
  if (lam(0) <= 1e-14 * lam(3)) {
    // Points on a circle to rounding precision: the null vector is the fit.
    A = es.eigenvectors().col(0);
  } else {
    // Hyper constraint matrix (Al-Sharadqah & Chernov 2009) for centred data.
    Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
    N(0, 0) = 8.0 * zbar;
    N(0, 3) = N(3, 0) = 2.0;
    N(1, 1) = N(2, 2) = 1.0;
    // M A = eta N A  <=>  W N^-1 W C = eta C with W = M^(1/2), C = W A; the
    // smallest positive eta (N has one negative eigenvalue) is the second.
    const Eigen::Matrix4d& V = es.eigenvectors();
    const Eigen::Matrix4d W = V * lam.cwiseSqrt().asDiagonal() * V.transpose();
    const Eigen::Matrix4d Winv = V * lam.cwiseSqrt().cwiseInverse().asDiagonal() * V.transpose();
    Eigen::Matrix4d Ninv = Eigen::Matrix4d::Zero();
    Ninv(0, 3) = Ninv(3, 0) = 0.5;
    Ninv(1, 1) = Ninv(2, 2) = 1.0;
    Ninv(3, 3) = -2.0 * zbar;  // inverse of [[8z, 2], [2, 0]] is [[0, 1/2], [1/2, -2z]]
    const Eigen::Matrix4d S = W * Ninv * W;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> gs(0.5 * (S + S.transpose()));
    A = Winv * gs.eigenvectors().col(1);
  }
  return A;
}

}  // namespace detail

CircleFit fit_circle_hyper(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  const Normalised n = normalise(points);
  if (auto bad = check_algebraic_input(n, "Hyper")) return *bad;
  return from_algebraic(hyper_parameters(n), n, points, "Hyper");
}

CircleFit fit_circle_taubin(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  const Normalised n = normalise(points);
  if (auto bad = check_algebraic_input(n, "Taubin")) return *bad;
  const double k = static_cast<double>(n.q.cols());
  double zmean = n.q.squaredNorm() / k;  // 1 after normalisation, kept general
  const double s = 2.0 * std::sqrt(zmean);
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < n.q.cols(); ++i) {
    const Eigen::Vector3d u((n.q.col(i).squaredNorm() - zmean) / s, n.q(0, i), n.q(1, i));
    M.noalias() += u * u.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(M);
  const Eigen::Vector3d a = es.eigenvectors().col(0);
  const double a0 = a(0) / s;
  return from_algebraic(Eigen::Vector4d(a0, a(1), a(2), -zmean * a0), n, points, "Taubin");
}

}  // namespace tinyline::hydrus_fitting
