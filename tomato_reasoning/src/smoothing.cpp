// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/smoothing.hpp"

#include "tomato_reasoning/param_tables.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>

#include "voxel_hash.hpp"

namespace tinyline::tomato_reasoning {

common::Status validate(const SmoothingParams& p) { return common::within_table(p); }

namespace {

// Voxel thinning that also keeps, per voxel, the view most of its points came from.
std::vector<Eigen::Vector3f> thin(const std::vector<Eigen::Vector3f>& points, const Indices& indices, double voxel_m,
                                  const std::vector<std::uint8_t>* view_of, std::vector<std::uint8_t>& views_out) {
  std::vector<Eigen::Vector3f> out;
  views_out.clear();
  Indices finite;
  finite.reserve(indices.size());
  for (int k : indices)
    if (points[static_cast<std::size_t>(k)].allFinite()) finite.push_back(k);
  auto view = [&](int k) { return view_of ? (*view_of)[static_cast<std::size_t>(k)] : std::uint8_t{0}; };
  if (voxel_m <= 0) {
    for (int k : finite) {
      out.push_back(points[static_cast<std::size_t>(k)]);
      views_out.push_back(view(k));
    }
    return out;
  }
  const detail::VoxelGrid grid(points, finite, voxel_m);
  out.reserve(grid.num_cells());
  for (std::size_t c = 0; c < grid.num_cells(); ++c) {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    int votes[256] = {0};
    std::uint8_t best = 0;
    for (const int* m = grid.begin(c); m != grid.end(c); ++m) {
      s += points[static_cast<std::size_t>(*m)].cast<double>();
      const std::uint8_t v = view(*m);
      if (++votes[v] > votes[best]) best = v;
    }
    out.push_back((s / static_cast<double>(grid.count(c))).cast<float>());
    views_out.push_back(best);
  }
  return out;
}

SmoothedCloud smooth(const std::vector<Eigen::Vector3f>& points, const Indices& indices, const SmoothingParams& p,
                     const std::vector<Eigen::Vector3f>& viewpoints, const std::vector<std::uint8_t>* view_of);

}  // namespace

std::vector<Eigen::Vector3f> voxel_thin(const std::vector<Eigen::Vector3f>& points, const Indices& indices,
                                        double voxel_m) {
  std::vector<std::uint8_t> views;
  return thin(points, indices, voxel_m, nullptr, views);
}

SmoothedCloud smooth_mls(const std::vector<Eigen::Vector3f>& points, const Indices& indices, const SmoothingParams& p,
                         const Eigen::Vector3f& viewpoint) {
  return smooth(points, indices, p, {viewpoint}, nullptr);
}

SmoothedCloud smooth_mls(const std::vector<Eigen::Vector3f>& points, const Indices& indices, const SmoothingParams& p,
                         const std::vector<Eigen::Vector3f>& viewpoints, const std::vector<std::uint8_t>& view_of) {
  SmoothedCloud out;
  if (view_of.size() != points.size()) {
    out.status = common::Status::invalid("view_of has " + std::to_string(view_of.size()) + " entries for " +
                                         std::to_string(points.size()) + " points");
    return out;
  }
  for (std::uint8_t v : view_of) {
    if (v >= viewpoints.size()) {
      out.status = common::Status::invalid("a point's view " + std::to_string(v) + " has no viewpoint (" +
                                           std::to_string(viewpoints.size()) + " given)");
      return out;
    }
  }
  return smooth(points, indices, p, viewpoints, &view_of);
}

namespace {

// Why the input cannot be smoothed, or empty.
std::string smoothing_input_problem(const std::vector<Eigen::Vector3f>& points, const Indices& indices,
                                    const SmoothingParams& p, const std::vector<Eigen::Vector3f>& viewpoints) {
  if (viewpoints.empty()) return "no viewpoint";
  if (const common::Status why = validate(p); !why.ok()) return "bad smoothing parameters: " + why.message;
  for (int k : indices) {
    if (k < 0 || static_cast<std::size_t>(k) >= points.size())
      return "index " + std::to_string(k) + " outside the " + std::to_string(points.size()) + " points";
  }
  return {};
}

// The weighted plane through a point's neighbourhood (Gaussian weights, as PCL).
struct LocalPlane {
  Eigen::Vector3d n, u, v;  ///< normal and the two in-plane axes
  Eigen::Vector3d base;     ///< the point's foot on the plane
  float curvature = 0.0f;
};

LocalPlane weighted_plane(const std::vector<Eigen::Vector3f>& pts, const std::vector<int>& nb,
                          const Eigen::Vector3d& qd, double h2, std::vector<double>& w) {
  w.resize(nb.size());
  double wsum = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < nb.size(); ++k) {
    const double d2 = (pts[static_cast<std::size_t>(nb[k])].cast<double>() - qd).squaredNorm();
    w[k] = std::exp(-d2 / h2);
    wsum += w[k];
    mean += w[k] * pts[static_cast<std::size_t>(nb[k])].cast<double>();
  }
  mean /= wsum;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < nb.size(); ++k) {
    const Eigen::Vector3d d = pts[static_cast<std::size_t>(nb[k])].cast<double>() - mean;
    cov += w[k] * d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Eigen::Vector3d& ev = es.eigenvalues();
  LocalPlane pl;
  pl.n = es.eigenvectors().col(0);
  pl.u = es.eigenvectors().col(1);
  pl.v = es.eigenvectors().col(2);
  const double trace = ev.sum();
  pl.curvature = trace > 0 ? static_cast<float>(ev[0] / trace) : 0.0f;
  pl.base = qd - (qd - mean).dot(pl.n) * pl.n;
  return pl;
}

// Weighted least squares height field h(u, v) = c0 + c1 u + c2 v + c3 u^2 + c4 uv + c5 v^2
// over the plane; moves the point onto it and takes its normal. False when
// ill-posed (a line of points): the caller keeps the plane.
bool fit_height_field(const std::vector<Eigen::Vector3f>& pts, const std::vector<int>& nb, const std::vector<double>& w,
                      const LocalPlane& pl, double radius_m, Eigen::Vector3d& proj, Eigen::Vector3d& normal) {
  // Normal equations from the weighted moments of (u, v) up to order four.
  const double s = 1.0 / radius_m;  // scale u, v to ~1 for conditioning
  double m[15] = {0};               // 1 u v uu uv vv uuu uuv uvv vvv uuuu uuuv uuvv uvvv vvvv
  double r6[6] = {0};
  for (std::size_t k = 0; k < nb.size(); ++k) {
    const Eigen::Vector3d d = pts[static_cast<std::size_t>(nb[k])].cast<double>() - pl.base;
    const double uu = d.dot(pl.u) * s, vv = d.dot(pl.v) * s, hh = d.dot(pl.n), wk = w[k];
    const double u2 = uu * uu, v2 = vv * vv, uv = uu * vv;
    m[0] += wk;
    m[1] += wk * uu;
    m[2] += wk * vv;
    m[3] += wk * u2;
    m[4] += wk * uv;
    m[5] += wk * v2;
    m[6] += wk * u2 * uu;
    m[7] += wk * u2 * vv;
    m[8] += wk * uu * v2;
    m[9] += wk * v2 * vv;
    m[10] += wk * u2 * u2;
    m[11] += wk * u2 * uv;
    m[12] += wk * u2 * v2;
    m[13] += wk * uv * v2;
    m[14] += wk * v2 * v2;
    const double wh = wk * hh;
    r6[0] += wh;
    r6[1] += wh * uu;
    r6[2] += wh * vv;
    r6[3] += wh * u2;
    r6[4] += wh * uv;
    r6[5] += wh * v2;
  }
  Eigen::Matrix<double, 6, 6> A;
  A << m[0], m[1], m[2], m[3], m[4], m[5], m[1], m[3], m[4], m[6], m[7], m[8], m[2], m[4], m[5], m[7], m[8], m[9], m[3],
      m[6], m[7], m[10], m[11], m[12], m[4], m[7], m[8], m[11], m[12], m[13], m[5], m[8], m[9], m[12], m[13], m[14];
  const Eigen::Matrix<double, 6, 1> b = Eigen::Map<const Eigen::Matrix<double, 6, 1>>(r6);
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(A);
  const Eigen::Matrix<double, 6, 1> c = ldlt.solve(b);
  if (ldlt.info() != Eigen::Success || !c.allFinite() || !(std::abs(c[0]) < radius_m)) return false;
  proj = pl.base + c[0] * pl.n;
  normal = (pl.n - c[1] * s * pl.u - c[2] * s * pl.v).normalized();
  return true;
}

SmoothedCloud smooth(const std::vector<Eigen::Vector3f>& points, const Indices& indices, const SmoothingParams& p,
                     const std::vector<Eigen::Vector3f>& viewpoints, const std::vector<std::uint8_t>* view_of) {
  SmoothedCloud out;
  if (std::string why = smoothing_input_problem(points, indices, p, viewpoints); !why.empty()) {
    out.status = common::Status::invalid(std::move(why));
    return out;
  }
  std::vector<std::uint8_t> pt_view;
  const std::vector<Eigen::Vector3f> pts = thin(points, indices, p.voxel_m, view_of, pt_view);
  if (pts.empty()) {
    out.status = common::Status::not_found(indices.empty() ? "no points to smooth" : "no finite points to smooth");
    return out;
  }
  Indices all(pts.size());
  for (std::size_t k = 0; k < pts.size(); ++k) all[k] = static_cast<int>(k);
  const detail::VoxelGrid grid(pts, all, p.search_radius_m);
  const double h2 = p.search_radius_m * p.search_radius_m;  // PCL's default Gaussian parameter
  std::vector<int> nb;
  std::vector<double> w;
  out.points.reserve(pts.size());
  out.normals.reserve(pts.size());
  out.curvature.reserve(pts.size());
  for (std::size_t qi = 0; qi < pts.size(); ++qi) {
    const Eigen::Vector3f& q = pts[qi];
    nb.clear();
    grid.for_each_within(pts, q, static_cast<float>(p.search_radius_m), [&](int k) { nb.push_back(k); });
    if (static_cast<int>(nb.size()) < p.min_neighbours) {
      ++out.dropped_isolated;
      continue;
    }
    const Eigen::Vector3d qd = q.cast<double>();
    const LocalPlane pl = weighted_plane(pts, nb, qd, h2, w);
    Eigen::Vector3d proj = pl.base;
    Eigen::Vector3d normal = pl.n;
    if (p.polynomial_order == 2 && nb.size() >= 6 &&
        !fit_height_field(pts, nb, w, pl, p.search_radius_m, proj, normal)) {
      proj = pl.base;
      normal = pl.n;
    }
    if (normal.dot(viewpoints[pt_view[qi]].cast<double>() - proj) < 0) normal = -normal;
    out.points.push_back((p.project_points ? proj : qd).cast<float>());
    out.normals.push_back(normal.cast<float>());
    out.curvature.push_back(pl.curvature);
    out.view.push_back(pt_view[qi]);
  }
  if (out.points.empty())
    out.status = common::Status::not_found("every point is isolated (fewer than " + std::to_string(p.min_neighbours) +
                                           " neighbours within " + std::to_string(p.search_radius_m) + " m)");
  return out;
}

}  // namespace

}  // namespace tinyline::tomato_reasoning
