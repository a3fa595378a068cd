// SPDX-License-Identifier: Apache-2.0
// DBSCAN (Ester et al. 1996; thesis 4.4.2, ref. [121]) with exact semantics,
// three neighbour searches, one labelling rule.
//
// Semantics (identical to scikit-learn's DBSCAN with a tree search, which a
// test checks on random and adversarial data):
//   - q is a neighbour of p when |p - q|^2 <= eps^2, the squared distance
//     summed over the coordinates in order, in double precision;
//   - p is a core point when it has at least min_points neighbours, itself
//     included (scikit-learn's min_samples);
//   - core points within eps of each other share a cluster (transitively);
//   - a non-core point within eps of a core point is a border point of that
//     core point's cluster; any other point is noise.
// Border rule: a border point within eps of core points of several clusters
// joins the cluster with the smallest id, and clusters are numbered in the
// order of their lowest-indexed core point. This is exactly what
// scikit-learn's expansion order produces, so labels match it one for one;
// it also makes the result independent of the neighbour search used.
//
// Invalid points (a non-finite coordinate) take no part: they are labelled
// kInvalid, are nobody's neighbour and are counted in the result.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <tinyline/common/status.hpp>

namespace tinyline::laser_clustering {

inline constexpr int kNoise = -1;    ///< label of a noise point
inline constexpr int kInvalid = -2;  ///< label of a point with a non-finite coordinate (or an invalid pixel)

struct DbscanParams {
  /// Neighbourhood radius, in the unit of the points (metres for scans). > 0.
  double eps = 0.01;
  /// Neighbours within eps, the point itself included, that make a core point. >= 1.
  int min_points = 3;
};

/// Parameter check shared by every entry point.
[[nodiscard]] common::Status validate(const DbscanParams& params);

struct DbscanResult {
  /// InvalidArgument when the parameters or the input were rejected (the
  /// per-point vectors are then empty); not ok before a run.
  common::Status status{common::StatusCode::InvalidArgument, "not run"};
  /// On an ok result without valid points: "empty input", "no valid points
  /// (5 invalid)"; empty otherwise (see num_invalid).
  std::string note;
  /// Per input point: a cluster id in [0, num_clusters), kNoise or kInvalid.
  std::vector<int> labels;
  /// Per input point: 1 for a core point.
  std::vector<std::uint8_t> is_core;
  int num_clusters = 0;
  std::size_t num_core = 0;
  std::size_t num_noise = 0;
  std::size_t num_invalid = 0;
};

/// General point sets of any dimension: one point per column (d x n), exact
/// radius search on a FLANN kd-tree. O(n log n) for bounded neighbourhoods.
[[nodiscard]] DbscanResult dbscan(const Eigen::Ref<const Eigen::MatrixXd>& points, const DbscanParams& params);

/// The textbook O(n^2) algorithm (every pair's distance). The reference the
/// other searches are tested and benchmarked against.
[[nodiscard]] DbscanResult dbscan_brute_force(const Eigen::Ref<const Eigen::MatrixXd>& points,
                                              const DbscanParams& params);

/// One line scan in pixel order, the fast path's input. Pixel i looks along
/// angle_rad[i] in the sensor's x-z plane (z forward, x along the line) and
/// hit at range_m[i]: its point is (range sin(angle), range cos(angle)).
/// Angles of valid pixels must be strictly monotone (either direction).
/// A pixel is invalid when its range is not finite or <= 0.
struct OrderedScanPoints {
  std::span<const double> angle_rad{};
  std::span<const double> range_m{};
  /// Optional extra coordinate per pixel (already scaled to metres-equivalent,
  /// e.g. log reflectance, see reflectance_clustering.hpp); empty if none. A
  /// non-finite value makes the pixel invalid.
  std::span<const double> feature{};
  /// Optional group id per pixel; pixels of different groups are never
  /// neighbours (as if they were infinitely far apart), a negative id makes
  /// the pixel invalid. Empty: one group. Used to run DBSCAN inside each
  /// group of a first clustering in one pass.
  std::span<const int> group{};
};

/// The points the fast path clusters, one per column: rows x, z (and the
/// feature when present); invalid pixels get NaN. Use it to run dbscan() on
/// exactly the same coordinates (groups are not represented).
[[nodiscard]] Eigen::MatrixXd to_points(const OrderedScanPoints& scan);

/// Fast path for ordered line scans. Two points at bearings differing by
/// dtheta are at least max(r1, r2) sin(dtheta) apart, so each pixel's
/// neighbours lie in a window of pixels around it: no tree, early exit once a
/// point is known to be core, and union-find that skips pairs already joined.
/// Same semantics and labels as dbscan() on to_points(scan). Reuses its
/// buffers between calls; not thread-safe (one per thread).
namespace detail {
template <bool with_feature, bool with_group>
class CompactScan;
}

class OrderedScanDbscan {
 public:
  [[nodiscard]] DbscanResult run(const OrderedScanPoints& scan, const DbscanParams& params);
  /// The same into `out`, reusing its storage: a loop that keeps one result
  /// allocates nothing per scan.
  void run(const OrderedScanPoints& scan, const DbscanParams& params, DbscanResult& out);
  /// sin and cos of the angles of the last scan run (cached: a sensor's
  /// pixel angles are the same scan after scan); callers that need the
  /// points' coordinates reuse them.
  [[nodiscard]] const std::vector<double>& sin_angle() const { return sin_; }
  [[nodiscard]] const std::vector<double>& cos_angle() const { return cos_; }

 private:
  // The stages of one run, in order (dbscan.cpp).
  template <bool with_feature, bool with_group>
  void run_impl(const OrderedScanPoints& scan, const DbscanParams& params, DbscanResult& r);
  void cache_trig(std::span<const double> angle_rad);
  template <bool with_feature, bool with_group>
  std::size_t compact(const OrderedScanPoints& scan, double eps, DbscanResult& r);
  template <bool with_feature, bool with_group>
  [[nodiscard]] detail::CompactScan<with_feature, with_group> view(int n, double eps) const;
  template <bool with_feature, bool with_group>
  std::size_t mark_core(const detail::CompactScan<with_feature, with_group>& s, int min_points, DbscanResult& r);
  void build_runs(int n, double eps2);
  template <bool with_feature, bool with_group>
  void link_runs(const detail::CompactScan<with_feature, with_group>& s);
  int number_clusters(int n, DbscanResult& r);
  template <bool with_feature, bool with_group>
  std::size_t label_borders(const detail::CompactScan<with_feature, with_group>& s, int min_points, DbscanResult& r);
  std::vector<double> trig_angle_, sin_, cos_;  // cached per sensor geometry
  std::vector<double> x_, z_, f_, theta_, range_, block_lo_, block_hi_, adjacent_, run_lo_, run_hi_;
  std::vector<int> g_, index_, run_end_, parent_, size_, cluster_of_root_;
  std::vector<std::uint8_t> core_;
};

/// One-shot convenience for OrderedScanDbscan::run.
[[nodiscard]] DbscanResult dbscan_ordered_scan(const OrderedScanPoints& scan, const DbscanParams& params);

}  // namespace tinyline::laser_clustering
