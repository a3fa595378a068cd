#include "laser_clustering/dbscan.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "dbscan_internal.hpp"

namespace tinyline::laser_clustering {

Validation validate(const DbscanParams& p) {
  if (!std::isfinite(p.eps) || p.eps <= 0.0) {
    return {false, fmt::format("DbscanParams.eps must be finite and > 0 (got {})", p.eps)};
  }
  if (p.min_points < 1) {
    return {false, fmt::format("DbscanParams.min_points must be >= 1 (got {})", p.min_points)};
  }
  return {};
}

namespace detail {

std::string check_points_input(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params) {
  if (auto v = validate(params); !v.valid) return v.reason;
  if (points.cols() > 0 && points.rows() == 0) {
    return fmt::format("points have dimension 0 ({} columns of no coordinates)", points.cols());
  }
  if (points.cols() >= std::numeric_limits<int>::max()) {
    return fmt::format("too many points ({}); at most {}", points.cols(), std::numeric_limits<int>::max() - 1);
  }
  return {};
}

std::size_t mark_valid(const Eigen::Ref<const Eigen::MatrixXd>& points, std::vector<std::uint8_t>& valid) {
  valid.assign(static_cast<std::size_t>(points.cols()), 0);
  std::size_t n = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (points.col(i).allFinite()) {
      valid[static_cast<std::size_t>(i)] = 1;
      ++n;
    }
  }
  return n;
}

void finish(DbscanResult& r) {
  r.ok = true;
  r.num_core = r.num_noise = r.num_invalid = 0;
  for (std::size_t i = 0; i < r.labels.size(); ++i) {
    r.num_core += r.is_core[i];
    r.num_noise += r.labels[i] == kNoise;
    r.num_invalid += r.labels[i] == kInvalid;
  }
  if (r.labels.empty()) {
    r.reason = "empty input";
  } else if (r.num_invalid == r.labels.size()) {
    r.reason = fmt::format("no valid points ({} invalid)", r.num_invalid);
  } else if (r.num_invalid > 0) {
    r.reason = fmt::format("{} invalid points ignored", r.num_invalid);
  }
}

DbscanResult label_from_neighbours(const std::vector<std::uint8_t>& valid, const NeighbourLists& lists,
                                   int min_points) {
  const std::size_t n = valid.size();
  DbscanResult r;
  r.labels.assign(n, kNoise);
  r.is_core.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i]) {
      r.labels[i] = kInvalid;
    } else if (lists.offset[i + 1] - lists.offset[i] >= static_cast<std::size_t>(min_points)) {
      r.is_core[i] = 1;
    }
  }
  std::vector<int> parent;
  DisjointSets sets;
  sets.reset(parent, n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!r.is_core[i]) continue;
    for (std::size_t k = lists.offset[i]; k < lists.offset[i + 1]; ++k) {
      const int j = lists.nbr[k];
      if (static_cast<std::size_t>(j) > i && r.is_core[static_cast<std::size_t>(j)]) sets.unite(static_cast<int>(i), j);
    }
  }
  // Clusters in the order of their lowest-indexed core point.
  std::vector<int> cluster_of_root(n, -1);
  int clusters = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!r.is_core[i]) continue;
    int& c = cluster_of_root[static_cast<std::size_t>(sets.find(static_cast<int>(i)))];
    if (c < 0) c = clusters++;
    r.labels[i] = c;
  }
  // Border points: the lowest-numbered cluster among adjacent core points.
  for (std::size_t i = 0; i < n; ++i) {
    if (!valid[i] || r.is_core[i]) continue;
    int best = kNoise;
    for (std::size_t k = lists.offset[i]; k < lists.offset[i + 1]; ++k) {
      const auto j = static_cast<std::size_t>(lists.nbr[k]);
      if (r.is_core[j] && (best == kNoise || r.labels[j] < best)) best = r.labels[j];
    }
    r.labels[i] = best;
  }
  r.num_clusters = clusters;
  finish(r);
  return r;
}

}  // namespace detail

DbscanResult dbscan_brute_force(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params) {
  DbscanResult bad;
  if (bad.reason = detail::check_points_input(points, params); !bad.reason.empty()) return bad;
  std::vector<std::uint8_t> valid;
  detail::mark_valid(points, valid);
  const double eps2 = params.eps * params.eps;
  const auto n = static_cast<std::size_t>(points.cols());
  detail::NeighbourLists lists;
  lists.offset.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    lists.offset[i] = lists.nbr.size();
    if (!valid[i]) continue;
    for (std::size_t j = 0; j < n; ++j) {
      if (valid[j] && detail::squared_distance(points, static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) <= eps2) {
        lists.nbr.push_back(static_cast<int>(j));
      }
    }
  }
  lists.offset[n] = lists.nbr.size();
  return detail::label_from_neighbours(valid, lists, params.min_points);
}

// ---------------------------------------------------------------------------
// Ordered line scans

namespace {

bool pixel_valid(const OrderedScanPoints& s, std::size_t i) {
  const double r = s.range_m[i];
  if (!std::isfinite(r) || r <= 0.0 || !std::isfinite(s.angle_rad[i])) return false;
  if (!s.group.empty() && s.group[i] < 0) return false;
  return s.feature.empty() || std::isfinite(s.feature[i]);
}

std::string check_scan_shape(const OrderedScanPoints& s) {
  if (s.range_m.size() != s.angle_rad.size()) {
    return fmt::format("scan has {} angles but {} ranges", s.angle_rad.size(), s.range_m.size());
  }
  if (!s.feature.empty() && s.feature.size() != s.range_m.size()) {
    return fmt::format("scan has {} ranges but {} feature values", s.range_m.size(), s.feature.size());
  }
  if (!s.group.empty() && s.group.size() != s.range_m.size()) {
    return fmt::format("scan has {} ranges but {} group ids", s.range_m.size(), s.group.size());
  }
  if (s.range_m.size() >= static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    return fmt::format("scan too long ({} pixels)", s.range_m.size());
  }
  return {};
}

}  // namespace

Eigen::MatrixXd to_points(const OrderedScanPoints& s) {
  const std::size_t n = std::min(s.angle_rad.size(), s.range_m.size());
  const bool with_f = !s.feature.empty() && s.feature.size() >= n;
  Eigen::MatrixXd p(with_f ? 3 : 2, static_cast<Eigen::Index>(n));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<Eigen::Index>(i);
    if (!pixel_valid(s, i)) {
      p.col(c).setConstant(nan);
      continue;
    }
    p(0, c) = s.range_m[i] * std::sin(s.angle_rad[i]);
    p(1, c) = s.range_m[i] * std::cos(s.angle_rad[i]);
    if (with_f) p(2, c) = s.feature[i];
  }
  return p;
}

DbscanResult OrderedScanDbscan::run(const OrderedScanPoints& scan, const DbscanParams& params) {
  DbscanResult r;
  if (auto v = validate(params); !v.valid) {
    r.reason = v.reason;
    return r;
  }
  if (r.reason = check_scan_shape(scan); !r.reason.empty()) return r;

  const std::size_t n_all = scan.range_m.size();
  const bool with_f = !scan.feature.empty();
  const bool with_g = !scan.group.empty();
  r.labels.assign(n_all, kInvalid);
  r.is_core.assign(n_all, 0);

  // Compact the valid pixels (same coordinates as to_points()).
  x_.clear();
  z_.clear();
  f_.clear();
  g_.clear();
  theta_.clear();
  index_.clear();
  for (std::size_t i = 0; i < n_all; ++i) {
    if (!pixel_valid(scan, i)) continue;
    x_.push_back(scan.range_m[i] * std::sin(scan.angle_rad[i]));
    z_.push_back(scan.range_m[i] * std::cos(scan.angle_rad[i]));
    if (with_f) f_.push_back(scan.feature[i]);
    if (with_g) g_.push_back(scan.group[i]);
    theta_.push_back(scan.angle_rad[i]);
    index_.push_back(static_cast<int>(i));
  }
  const auto n = static_cast<int>(index_.size());

  // Strictly monotone bearings; a descending scan is walked mirrored.
  if (n >= 2) {
    const bool ascending = theta_[1] > theta_[0];
    for (int k = 1; k < n; ++k) {
      const bool ok = ascending ? theta_[k] > theta_[k - 1] : theta_[k] < theta_[k - 1];
      if (!ok) {
        r.labels.clear();
        r.is_core.clear();
        r.reason = fmt::format(
            "pixel angles must be strictly monotone over valid pixels: pixel {} at {} rad after pixel {} at {} rad",
            index_[k], theta_[k], index_[k - 1], theta_[k - 1]);
        return r;
      }
    }
    if (!ascending) {
      for (double& t : theta_) t = -t;
    }
  }

  const double eps = params.eps;
  const double eps2 = eps * eps;
  // Squared distance; pixels of different groups are infinitely far apart.
  auto d2 = [&](int i, int j) {
    if (with_g && g_[i] != g_[j]) return std::numeric_limits<double>::infinity();
    double t = x_[i] - x_[j];
    double s = t * t;
    t = z_[i] - z_[j];
    s += t * t;
    if (with_f) {
      t = f_[i] - f_[j];
      s += t * t;
    }
    return s;
  };
  // A neighbour j of i satisfies |dtheta| <= asin(eps / r_i); widened by a
  // hair so rounding never hides a pair at exactly eps.
  half_window_.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const double ratio = eps / scan.range_m[static_cast<std::size_t>(index_[i])];
    half_window_[i] = ratio >= 1.0 ? std::numbers::pi * 2.0 : std::asin(ratio) * (1.0 + 1e-9) + 1e-12;
  }

  // Core flags: count outwards from each pixel, stop once min_points is reached.
  for (int i = 0; i < n; ++i) {
    int count = 1;
    const double h = half_window_[i];
    bool left = true, right = true;
    for (int k = 1; count < params.min_points && (left || right); ++k) {
      if (left) {
        const int j = i - k;
        if (j < 0 || theta_[i] - theta_[j] > h) {
          left = false;
        } else if (d2(i, j) <= eps2) {
          ++count;
        }
      }
      if (right && count < params.min_points) {
        const int j = i + k;
        if (j >= n || theta_[j] - theta_[i] > h) {
          right = false;
        } else if (d2(i, j) <= eps2) {
          ++count;
        }
      }
    }
    r.is_core[static_cast<std::size_t>(index_[i])] = count >= params.min_points ? 1 : 0;
  }
  auto core = [&](int i) { return r.is_core[static_cast<std::size_t>(index_[i])] != 0; };

  // Core-core edges, right to left: when i is processed, everything right of
  // it is already joined, so most pairs are skipped without a distance.
  detail::DisjointSets sets;
  sets.reset(parent_, static_cast<std::size_t>(n));
  for (int i = n - 1; i >= 0; --i) {
    if (!core(i)) continue;
    const double h = half_window_[i];
    for (int j = i + 1; j < n && theta_[j] - theta_[i] <= h; ++j) {
      if (core(j) && sets.find(i) != sets.find(j) && d2(i, j) <= eps2) sets.unite(i, j);
    }
  }
  cluster_of_root_.assign(static_cast<std::size_t>(n), -1);
  int clusters = 0;
  for (int i = 0; i < n; ++i) {
    if (!core(i)) continue;
    int& c = cluster_of_root_[static_cast<std::size_t>(sets.find(i))];
    if (c < 0) c = clusters++;
    r.labels[static_cast<std::size_t>(index_[i])] = c;
  }
  // Border points: the lowest-numbered cluster among core points within eps.
  for (int i = 0; i < n; ++i) {
    if (core(i)) continue;
    int best = kNoise;
    const double h = half_window_[i];
    for (int j = i - 1; j >= 0 && theta_[i] - theta_[j] <= h; --j) {
      const int lj = r.labels[static_cast<std::size_t>(index_[j])];
      if (core(j) && (best == kNoise || lj < best) && d2(i, j) <= eps2) best = lj;
    }
    for (int j = i + 1; j < n && theta_[j] - theta_[i] <= h; ++j) {
      const int lj = r.labels[static_cast<std::size_t>(index_[j])];
      if (core(j) && (best == kNoise || lj < best) && d2(i, j) <= eps2) best = lj;
    }
    r.labels[static_cast<std::size_t>(index_[i])] = best;
  }
  r.num_clusters = clusters;
  detail::finish(r);
  return r;
}

DbscanResult dbscan_ordered_scan(const OrderedScanPoints& scan, const DbscanParams& params) {
  OrderedScanDbscan d;
  return d.run(scan, params);
}

}  // namespace tinyline::laser_clustering
