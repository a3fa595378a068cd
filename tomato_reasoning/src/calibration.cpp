// SPDX-License-Identifier: Apache-2.0
// GCC 12 reports a false -Warray-bounds inside Eigen's Umeyama (PCL's ICP
// instantiates it for float) at -O2; the report comes at instantiation, so
// the whole file ignores it.
#pragma GCC diagnostic ignored "-Warray-bounds"

#include "tomato_reasoning/calibration.hpp"

#include <cmath>

#include <Eigen/Dense>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>

namespace tinyline::tomato_reasoning {

common::Status validate(const DepthCorrectionParams& p) {
  if (p.cells_u < 1 || p.cells_v < 1 || p.cells_u * p.cells_v > 10000)
    return common::Status::invalid("cells_u x cells_v must be 1..10000 cells");
  if (p.degree < 0 || p.degree > 6) return common::Status::invalid("degree must be 0..6");
  return common::Status{};
}

namespace {
int cell_of(const DepthCorrectionParams& p, int width, int height, int u, int v) {
  const int cu = std::min(p.cells_u - 1, u * p.cells_u / width), cv = std::min(p.cells_v - 1, v * p.cells_v / height);
  return cv * p.cells_u + cu;
}
}  // namespace

double DepthCorrection::correct(int u, int v, double z) const {
  if (!status.ok() || u < 0 || v < 0 || u >= width || v >= height || !std::isfinite(z)) return z;
  double t = cell_offset_m[std::size_t(cell_of(params, width, height, u, v))], zk = 1.0;
  for (double c : theta) t += c * (zk *= z);
  return z + t;
}

DepthCorrection fit_depth_correction(const std::vector<DepthSample>& samples, int width, int height,
                                     const DepthCorrectionParams& p) {
  DepthCorrection d;
  d.params = p;
  d.width = width;
  d.height = height;
  if (const common::Status bad = validate(p); !bad.ok()) return d.status = bad, d;
  if (width <= 0 || height <= 0) return d.status = common::Status::invalid("image size must be positive"), d;
  const int cells = p.cells_u * p.cells_v, n = cells + p.degree;
  // z_true - z = Z(cell) + sum_k c_k z^k: linear in the unknowns; normal equations.
  Eigen::MatrixXd AtA = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd Atb = Eigen::VectorXd::Zero(n);
  std::vector<int> count(std::size_t(cells), 0);
  double sse_before = 0;
  for (const auto& s : samples) {
    if (!std::isfinite(s.measured_m) || !std::isfinite(s.true_m) || s.u < 0 || s.v < 0 || s.u >= width || s.v >= height)
      continue;
    const int c = cell_of(p, width, height, s.u, s.v);
    Eigen::VectorXd a = Eigen::VectorXd::Zero(n);
    a(c) = 1.0;
    double zk = 1.0;
    for (int k = 0; k < p.degree; ++k) a(cells + k) = (zk *= s.measured_m);
    const double b = s.true_m - s.measured_m;
    // The row touches one cell and the degree terms: update only those entries.
    AtA(c, c) += 1.0;
    for (int k = 0; k < p.degree; ++k) {
      AtA(c, cells + k) += a(cells + k);
      AtA(cells + k, c) += a(cells + k);
      for (int j = 0; j < p.degree; ++j) AtA(cells + k, cells + j) += a(cells + k) * a(cells + j);
      Atb(cells + k) += a(cells + k) * b;
    }
    Atb(c) += b;
    ++count[std::size_t(c)];
    sse_before += b * b;
    ++d.samples_used;
  }
  if (d.samples_used < std::size_t(n)) {
    d.status = common::Status::invalid(std::to_string(d.samples_used) + " usable samples, fewer than the " +
                                       std::to_string(n) + " unknowns");
    return d;
  }
  // Cells without samples: pin their offset to 0 (a unit row keeps the system regular).
  for (int c = 0; c < cells; ++c)
    if (count[std::size_t(c)] == 0) {
      AtA(c, c) = 1.0;
      ++d.empty_cells;
    }
  const Eigen::VectorXd x = AtA.ldlt().solve(Atb);
  if (!x.allFinite())
    return d.status = common::Status::invalid("the depth range is too narrow to separate Z(u, v) from theta(z)"), d;
  d.cell_offset_m.assign(x.data(), x.data() + cells);
  d.theta.assign(x.data() + cells, x.data() + n);
  d.status = {};
  double sse_after = 0;
  for (const auto& s : samples) {
    if (!std::isfinite(s.measured_m) || !std::isfinite(s.true_m) || s.u < 0 || s.v < 0 || s.u >= width || s.v >= height)
      continue;
    const double e = s.true_m - d.correct(s.u, s.v, s.measured_m);
    sse_after += e * e;
  }
  d.rms_before_m = std::sqrt(sse_before / double(d.samples_used));
  d.rms_after_m = std::sqrt(sse_after / double(d.samples_used));
  if (d.empty_cells > 0) d.note = std::to_string(d.empty_cells) + " cells without samples keep Z = 0";
  return d;
}

namespace {
pcl::PointCloud<pcl::PointXYZ>::Ptr thinned(const ColorCloud& c, double voxel_m, double max_range_m) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr raw(new pcl::PointCloud<pcl::PointXYZ>);
  raw->reserve(c.size());
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c.finite(i) && c.xyz[i].norm() <= max_range_m)
      raw->push_back(pcl::PointXYZ(c.xyz[i].x(), c.xyz[i].y(), c.xyz[i].z()));
  if (raw->empty() || voxel_m <= 0) return raw;
  pcl::PointCloud<pcl::PointXYZ>::Ptr out(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::VoxelGrid<pcl::PointXYZ> vg;
  vg.setInputCloud(raw);
  vg.setLeafSize(float(voxel_m), float(voxel_m), float(voxel_m));
  vg.filter(*out);
  return out;
}
}  // namespace

HandToHeadResult calibrate_hand_to_head(const ColorCloud& head, const ColorCloud& hand, const Eigen::Isometry3d& guess,
                                        const HandToHeadParams& p) {
  HandToHeadResult r;
  r.T_head_hand = guess;
  auto fail = [&r](common::Status s) { return r.status = std::move(s), r; };
  if (const auto bad = check_cloud(head); !bad.ok()) return fail(bad.within("head cloud"));
  if (const auto bad = check_cloud(hand); !bad.ok()) return fail(bad.within("hand cloud"));
  if (!guess.matrix().allFinite()) return fail(common::Status::invalid("the guess is not finite"));
  if (!(p.max_correspondence_m > 0) || p.max_iterations < 1)
    return fail(common::Status::invalid("max_correspondence_m and max_iterations must be positive"));
  const auto target = thinned(head, p.voxel_m, p.max_range_m), source = thinned(hand, p.voxel_m, p.max_range_m);
  if (target->size() < 10 || source->size() < 10)
    return fail(common::Status::not_found("too few points with depth (head " + std::to_string(target->size()) +
                                          ", hand " + std::to_string(source->size()) + ")"));
  // Coarse to fine: the correspondence distance shrinks so that the last
  // rounds pair only points that truly face each other.
  pcl::PointCloud<pcl::PointXYZ> aligned;
  Eigen::Matrix4f T_current = guess.matrix().cast<float>();
  bool converged = true;
  for (const double scale : {1.0, 1.0 / 3.0, 1.0 / 6.0}) {
    pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> icp;
    icp.setInputSource(source);
    icp.setInputTarget(target);
    icp.setMaxCorrespondenceDistance(std::max(p.max_correspondence_m * scale, 1.5 * p.voxel_m));
    icp.setMaximumIterations(p.max_iterations);
    icp.setTransformationEpsilon(1e-10);
    icp.setEuclideanFitnessEpsilon(1e-12);
    icp.align(aligned, T_current);
    converged = converged && icp.hasConverged();
    T_current = icp.getFinalTransformation();
  }
  Eigen::Isometry3d T(T_current.cast<double>());
  // Re-orthonormalise (float accumulation).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(T.linear(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  r.T_head_hand = T;
  // Pairs within the correspondence distance after alignment.
  pcl::search::KdTree<pcl::PointXYZ> tree;
  tree.setInputCloud(target);
  std::vector<int> idx(1);
  std::vector<float> d2(1);
  double sse = 0;
  int paired = 0;
  for (const auto& q : aligned) {
    if (tree.nearestKSearch(q, 1, idx, d2) == 1 && d2[0] <= p.max_correspondence_m * p.max_correspondence_m) {
      sse += d2[0];
      ++paired;
    }
  }
  r.overlap = double(paired) / double(aligned.size());
  r.rms_m = paired ? std::sqrt(sse / paired) : 0.0;
  if (!converged)
    r.status = common::Status::not_found("ICP did not converge");
  else if (r.overlap < p.min_overlap)
    r.status = common::Status::not_found(
        "only " + std::to_string(int(100 * r.overlap)) +
        "% of the hand's points found a partner (the views barely overlap, or the guess is far off)");
  else
    r.status = {};
  return r;
}

}  // namespace tinyline::tomato_reasoning
