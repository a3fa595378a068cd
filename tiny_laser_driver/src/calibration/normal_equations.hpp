// Weighted ridge least squares on sparse rows through normal equations that
// can be added and subtracted, so grouped cross-validation solves each fold
// from (total - fold) without another pass over the data.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include <Eigen/Dense>

namespace tinyline::tiny_laser_driver::detail {

using Entries = std::vector<std::pair<std::size_t, double>>;

struct NormalEquations {
  Eigen::MatrixXd gram;  // upper triangle filled while accumulating
  Eigen::VectorXd rhs;
  double weight = 0.0;

  NormalEquations() = default;
  explicit NormalEquations(std::size_t p) : gram(Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(p), static_cast<Eigen::Index>(p))),
                                            rhs(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p))) {}

  void add(const Entries& e, double y, double w) {
    for (std::size_t i = 0; i < e.size(); ++i) {
      const auto ci = static_cast<Eigen::Index>(e[i].first);
      const double wi = w * e[i].second;
      rhs[ci] += wi * y;
      for (std::size_t j = i; j < e.size(); ++j) {
        const auto cj = static_cast<Eigen::Index>(e[j].first);
        if (ci <= cj) {
          gram(ci, cj) += wi * e[j].second;
        } else {
          gram(cj, ci) += wi * e[j].second;
        }
      }
    }
    weight += w;
  }
  NormalEquations& operator+=(const NormalEquations& o) {
    gram += o.gram;
    rhs += o.rhs;
    weight += o.weight;
    return *this;
  }
  NormalEquations& operator-=(const NormalEquations& o) {
    gram -= o.gram;
    rhs -= o.rhs;
    weight -= o.weight;
    return *this;
  }

  /// Solves (G + diag(ridge)) c = rhs. Columns that no row touched get 0.
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& ridge) const {
    Eigen::MatrixXd g = gram.selfadjointView<Eigen::Upper>();
    const Eigen::Index p = g.rows();
    for (Eigen::Index i = 0; i < p; ++i) {
      g(i, i) += ridge[i];
      if (g(i, i) <= 0.0) g(i, i) = 1.0;  // untouched column: coefficient 0
    }
    Eigen::LDLT<Eigen::MatrixXd> ldlt(g);
    Eigen::VectorXd c = ldlt.solve(rhs);
    if (!c.allFinite()) c = g.completeOrthogonalDecomposition().solve(rhs);
    return c;
  }
};

inline double dot(const Entries& e, const Eigen::VectorXd& c) {
  double s = 0.0;
  for (const auto& [i, v] : e) s += v * c[static_cast<Eigen::Index>(i)];
  return s;
}

}  // namespace tinyline::tiny_laser_driver::detail
