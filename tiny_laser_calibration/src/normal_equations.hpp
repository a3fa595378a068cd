// SPDX-License-Identifier: Apache-2.0
// Weighted ridge least squares on sparse rows through normal equations that
// can be added and subtracted, so grouped cross-validation solves each fold
// from (total - fold) without another pass over the data.
#pragma once

#include <cstddef>
#include <utility>
#include <vector>

#include <Eigen/Dense>

namespace tinyline::tiny_laser_calibration::detail {

using Entries = std::vector<std::pair<std::size_t, double>>;

struct NormalEquations {
  Eigen::MatrixXd gram;  // upper triangle filled while accumulating
  Eigen::VectorXd rhs;
  double weight = 0.0;

  NormalEquations() = default;
  explicit NormalEquations(std::size_t p)
      : gram(Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(p), static_cast<Eigen::Index>(p))),
        rhs(Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p))) {}

  void add(const Entries& e, double y, double w) { add(e.data(), e.size(), y, w); }

  // Raw pointers: this loop runs once per row and solve, and Eigen's checked
  // element access dominates it in debug and sanitizer builds.
  void add(const std::pair<std::size_t, double>* e, std::size_t n, double y, double w) {
    double* g = gram.data();
    double* h = rhs.data();
    const std::size_t p = static_cast<std::size_t>(gram.rows());
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t ci = e[i].first;
      const double wi = w * e[i].second;
      h[ci] += wi * y;
      for (std::size_t j = i; j < n; ++j) {
        const std::size_t cj = e[j].first;
        const double v = wi * e[j].second;
        if (ci <= cj) {
          g[ci + cj * p] += v;
        } else {
          g[cj + ci * p] += v;
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

inline double dot(const std::pair<std::size_t, double>* e, std::size_t n, const double* c) {
  double s = 0.0;
  for (std::size_t k = 0; k < n; ++k) s += e[k].second * c[e[k].first];
  return s;
}

inline double dot(const Entries& e, const Eigen::VectorXd& c) { return dot(e.data(), e.size(), c.data()); }

/// Sparse rows, stored back to back (compressed rows).
struct SparseRows {
  std::vector<std::pair<std::size_t, double>> entries;
  std::vector<std::size_t> start{0};  ///< row i holds entries[start[i], start[i + 1])

  void clear() {
    entries.clear();
    start.assign(1, 0);
  }
  void push(const Entries& e) {
    entries.insert(entries.end(), e.begin(), e.end());
    start.push_back(entries.size());
  }
  [[nodiscard]] std::size_t rows() const { return start.size() - 1; }
  [[nodiscard]] const std::pair<std::size_t, double>* row(std::size_t i) const { return entries.data() + start[i]; }
  [[nodiscard]] std::size_t size(std::size_t i) const { return start[i + 1] - start[i]; }
};

}  // namespace tinyline::tiny_laser_calibration::detail
