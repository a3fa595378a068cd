// SPDX-License-Identifier: Apache-2.0
// Levenberg-Marquardt for small nonlinear least-squares problems (a circle, a
// sphere, a few calibration constants): the project's one damped
// Gauss-Newton loop. The problem supplies the model; this file decides the
// damping, which steps to take and when to stop.
//
// A Problem offers, for its parameter vector type V (an Eigen vector, fixed
// or dynamic size) and the matching matrix type:
//
//   auto linearise(const V& x)        -> std::pair<Matrix, V>: J^T W J and
//                                        J^T W r at x (r the residuals)
//   double cost(V& candidate)         -> r^T W r at the candidate; may move the
//                                        candidate onto the feasible set (the
//                                        value x becomes when it is accepted);
//                                        +inf where the model is undefined
//   void accept()                     -> the last costed candidate is the new x
//   bool converged(double old_cost, double new_cost, const V& step)
//                                     -> after an accepted step: stop here?
//
// Each iteration linearises once, then solves the damped normal equations
// (J^T W J + lambda diag(max(J^T W J, 1e-12))) step = -J^T W r (Marquardt's
// scaling) with growing lambda until a step lowers the cost.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace tinyline::common {

/// Marquardt's damping of a normal matrix: A + lambda diag(max(A_kk, 1e-12))
/// (the floor keeps a parameter no residual depends on from making the
/// system singular).
template <class Matrix>
[[nodiscard]] Matrix marquardt_damped(Matrix a, double lambda) {
  for (Eigen::Index k = 0; k < a.rows(); ++k) a(k, k) += lambda * std::max(a(k, k), 1e-12);
  return a;
}

struct LevenbergMarquardtSettings {
  /// Linearisations at most.
  int max_iterations = 50;
  /// Damped solves per linearisation; when none lowers the cost the run
  /// stops, at a minimum to rounding.
  int max_tries = 10;
  /// No solve is tried once lambda reaches this.
  double max_lambda = std::numeric_limits<double>::infinity();
  double initial_lambda = 1e-3;
  /// A rejected step (or a non-finite one) multiplies lambda by this.
  double increase = 10.0;
  /// An accepted step sets lambda to max(lambda * decrease / decrease_divisor,
  /// min_lambda). (A factor like 1/3 is written as a divisor of 3, so that it
  /// is exact.)
  double decrease = 0.1;
  double decrease_divisor = 1.0;
  double min_lambda = 1e-12;
  /// A step shorter than this (Euclidean norm, in the parameters' units) is
  /// not tried: the run stops there, converged.
  double min_step = 0.0;
  /// Accept a step that leaves the cost unchanged (a flat valley floor).
  bool accept_equal_cost = false;
};

struct LevenbergMarquardtResult {
  double cost = 0.0;   ///< at the final x
  int iterations = 0;  ///< linearisations begun
  /// Stopped by the problem's test, by a step under min_step, or because no
  /// damping lowered the cost; false: max_iterations ran out.
  bool converged = false;
};

/// Minimises the problem's cost from x (whose cost is `cost`), updating x.
template <class Problem, class Vector>
LevenbergMarquardtResult levenberg_marquardt(Problem& problem, Vector& x, double cost,
                                             const LevenbergMarquardtSettings& s = {}) {
  LevenbergMarquardtResult out;
  double lambda = s.initial_lambda;
  while (out.iterations < s.max_iterations && !out.converged) {
    ++out.iterations;
    const auto [normal, gradient] = problem.linearise(x);
    bool accepted = false;
    for (int tries = 0; tries < s.max_tries && lambda < s.max_lambda && !accepted && !out.converged; ++tries) {
      const Vector step = marquardt_damped(normal, lambda).ldlt().solve(-gradient);
      if (!step.allFinite()) {
        lambda *= s.increase;
        continue;
      }
      if (step.norm() < s.min_step) {
        out.converged = true;
        break;
      }
      Vector candidate = x + step;
      const double c = problem.cost(candidate);
      if (std::isfinite(c) && (c < cost || (s.accept_equal_cost && c == cost))) {
        problem.accept();
        x = candidate;
        const double old = cost;
        cost = c;
        lambda = std::max(lambda * s.decrease / s.decrease_divisor, s.min_lambda);
        accepted = true;
        out.converged = problem.converged(old, cost, step);
      } else {
        lambda *= s.increase;
      }
    }
    if (!accepted) out.converged = true;  // no damping lowers the cost: a minimum to rounding
  }
  out.cost = cost;
  return out;
}

}  // namespace tinyline::common
