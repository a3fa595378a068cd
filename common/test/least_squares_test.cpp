// SPDX-License-Identifier: Apache-2.0
// The one Levenberg-Marquardt loop, on a small nonlinear fit.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <tinyline/common/least_squares.hpp>

namespace c = tinyline::common;

namespace {

// y = a exp(b t): two parameters, residual r_i = a exp(b t_i) - y_i.
struct ExponentialFit {
  std::vector<double> t, y;
  int accepted = 0;
  double cost_of(const Eigen::Vector2d& x) const {
    double e = 0.0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      const double r = x(0) * std::exp(x(1) * t[i]) - y[i];
      e += r * r;
    }
    return e;
  }
  std::pair<Eigen::Matrix2d, Eigen::Vector2d> linearise(const Eigen::Vector2d& x) const {
    Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
    Eigen::Vector2d g = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < t.size(); ++i) {
      const double e = std::exp(x(1) * t[i]);
      const Eigen::Vector2d j(e, x(0) * t[i] * e);
      h += j * j.transpose();
      g += j * (x(0) * e - y[i]);
    }
    return {h, g};
  }
  double cost(Eigen::Vector2d& candidate) const { return cost_of(candidate); }
  void accept() { ++accepted; }
  bool converged(double old_cost, double new_cost, const Eigen::Vector2d&) const {
    return old_cost - new_cost <= 1e-14 * old_cost;
  }
};

ExponentialFit exponential_data() {
  ExponentialFit f;
  for (int i = 0; i < 20; ++i) {
    const double t = 0.1 * i;
    f.t.push_back(t);
    f.y.push_back(2.0 * std::exp(-1.5 * t) + 1e-3 * std::sin(7.0 * i));  // a little deterministic noise
  }
  return f;
}

}  // namespace

TEST(LevenbergMarquardt, FitsANonlinearModelFromAFarStart) {
  ExponentialFit f = exponential_data();
  Eigen::Vector2d x(0.5, 0.5);
  const auto r = c::levenberg_marquardt(f, x, f.cost_of(x));
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(x(0), 2.0, 2e-3);
  EXPECT_NEAR(x(1), -1.5, 2e-3);
  EXPECT_DOUBLE_EQ(r.cost, f.cost_of(x));
  EXPECT_LT(r.cost, 1e-4);
  EXPECT_GT(f.accepted, 0);
  EXPECT_LE(r.iterations, 50);
}

TEST(LevenbergMarquardt, RunsOutOfIterationsUnconverged) {
  ExponentialFit f = exponential_data();
  Eigen::Vector2d x(0.5, 0.5);
  c::LevenbergMarquardtSettings s;
  s.max_iterations = 1;
  const auto r = c::levenberg_marquardt(f, x, f.cost_of(x), s);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(f.accepted, 1);
}

TEST(LevenbergMarquardt, AStepUnderMinStepEndsTheRunAtTheStart) {
  ExponentialFit f = exponential_data();
  Eigen::Vector2d x(2.0, -1.5);
  c::LevenbergMarquardtSettings s;
  s.min_step = 1.0;  // every step from near the optimum is shorter
  const auto r = c::levenberg_marquardt(f, x, f.cost_of(x), s);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_EQ(f.accepted, 0);
  EXPECT_EQ(x, Eigen::Vector2d(2.0, -1.5));
}

TEST(LevenbergMarquardt, AnUndefinedModelIsNeverAccepted) {
  struct Nowhere : ExponentialFit {
    double cost(Eigen::Vector2d&) const { return std::numeric_limits<double>::infinity(); }
  } f;
  static_cast<ExponentialFit&>(f) = exponential_data();
  Eigen::Vector2d x(0.5, 0.5);
  const auto r = c::levenberg_marquardt(f, x, f.cost_of(x));
  EXPECT_TRUE(r.converged);  // no damping lowers the cost
  EXPECT_EQ(f.accepted, 0);
  EXPECT_EQ(x, Eigen::Vector2d(0.5, 0.5));
}

TEST(LevenbergMarquardt, ACandidateMovedOntoTheFeasibleSetIsWhatXBecomes) {
  struct Clamped : ExponentialFit {
    double cost(Eigen::Vector2d& candidate) const {
      candidate(1) = std::max(candidate(1), -1.0);  // b >= -1
      return cost_of(candidate);
    }
  } f;
  static_cast<ExponentialFit&>(f) = exponential_data();
  Eigen::Vector2d x(0.5, 0.5);
  (void)c::levenberg_marquardt(f, x, f.cost_of(x));
  EXPECT_GE(x(1), -1.0);
  EXPECT_NEAR(x(1), -1.0, 1e-12);
}

TEST(LevenbergMarquardt, MarquardtDampingScalesTheDiagonal) {
  Eigen::Matrix2d a;
  a << 4.0, 1.0, 1.0, 0.0;
  const Eigen::Matrix2d d = c::marquardt_damped(a, 0.5);
  EXPECT_DOUBLE_EQ(d(0, 0), 6.0);
  EXPECT_DOUBLE_EQ(d(1, 1), 0.5e-12);
  EXPECT_DOUBLE_EQ(d(0, 1), 1.0);
}
