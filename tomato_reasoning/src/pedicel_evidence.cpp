// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/pedicel_evidence.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace tinyline::tomato_reasoning {

namespace {

constexpr double kDeg = M_PI / 180.0;

struct Candidate {
  Eigen::Vector3d p;    // the point, pushed back to the rod's axis
  Eigen::Vector3d dir;  // unit, from the fruit's centre
  double beyond_m;      // distance beyond the fruit's surface
};

// log of the vMF normalising constant on S^2, kappa / (2 pi (1 - e^{-2 kappa})).
double log_vmf_constant(double kappa) {
  if (kappa < 1e-9) return -std::log(4.0 * M_PI);
  return std::log(kappa) - std::log(2.0 * M_PI) - std::log1p(-std::exp(-2.0 * kappa));
}

// The green points in this fruit's shell, nearer it than any other fruit,
// within the prior's cone.
std::vector<Candidate> shell_points(const GreenPoints& g, const std::vector<Sphere>& spheres, int index,
                                    const Eigen::Vector3d& prior_dir, const PedicelEvidenceParams& P) {
  const Sphere& s = spheres[static_cast<std::size_t>(index)];
  const double lo = s.radius_m - P.shell_inner_m, hi = s.radius_m + P.shell_outer_m;
  const double cos_prior = std::cos(P.max_prior_angle_deg * kDeg);
  std::vector<Candidate> out;
  for (std::size_t k = 0; k < g.xyz.size(); ++k) {
    Eigen::Vector3d p = g.xyz[k].cast<double>();
    const Eigen::Vector3d d0 = p - s.centre;
    if (d0.squaredNorm() > hi * hi || d0.squaredNorm() < lo * lo) continue;
    const Eigen::Vector3d eye = g.viewpoints[g.view[k]].cast<double>();
    p += P.rod_radius_m * (p - eye).normalized();
    const Eigen::Vector3d d = p - s.centre;
    const double dist = d.norm();
    if (!(dist > 1e-9) || d.dot(prior_dir) < cos_prior * dist) continue;
    bool other = false;
    for (std::size_t j = 0; j < spheres.size() && !other; ++j)
      other = static_cast<int>(j) != index && (p - spheres[j].centre).norm() - spheres[j].radius_m < dist - s.radius_m;
    if (!other) out.push_back({p, d / dist, dist - s.radius_m});
  }
  return out;
}

// Mean shift on the unit sphere from `start`: the mean direction of the
// candidates within `cos_win` of the current one, a few times.
Eigen::Vector3d mode_direction(const std::vector<Candidate>& c, Eigen::Vector3d m, double cos_win) {
  for (int it = 0; it < 8; ++it) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& x : c)
      if (x.dir.dot(m) >= cos_win) sum += x.dir;
    if (!(sum.norm() > 1e-12)) break;
    const Eigen::Vector3d next = sum.normalized();
    const bool done = next.dot(m) > std::cos(0.05 * kDeg);
    m = next;
    if (done) break;
  }
  return m;
}

// The principal axes of the candidates' points: eigenvectors in the columns,
// eigenvalues ascending.
struct Axes {
  Eigen::Matrix3d vectors = Eigen::Matrix3d::Identity();
  Eigen::Vector3d values = Eigen::Vector3d::Zero();
};

Axes axes_of(const std::vector<Candidate>& c) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& x : c) mean += x.p;
  mean /= static_cast<double>(c.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& x : c) cov += (x.p - mean) * (x.p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov / static_cast<double>(c.size()));
  return {es.eigenvectors(), es.eigenvalues()};
}

Eigen::Vector3d along(const Eigen::Vector3d& v, const Eigen::Vector3d& mode) { return v.dot(mode) < 0 ? -v : v; }

// The seen direction: the line through the pedicel's first centimetres (a
// curved pedicel's tangent, whatever the centre's error), else the normal of
// the calyx's disc, else the bundle's mean direction from the centre.
Eigen::Vector3d seen_direction(const std::vector<Candidate>& c, const Eigen::Vector3d& mode,
                               const PedicelEvidenceParams& P, PedicelSighting& out) {
  const double cos_win = std::cos(P.cone_deg * kDeg), cos_calyx = std::cos(P.calyx_cone_deg * kDeg);
  std::vector<Candidate> pedicel, calyx;
  for (const auto& x : c) {
    if (x.beyond_m > P.calyx_depth_m && x.beyond_m <= P.line_reach_m && x.dir.dot(mode) >= cos_win)
      pedicel.push_back(x);
    if (x.beyond_m <= P.calyx_depth_m && x.dir.dot(mode) >= cos_calyx) calyx.push_back(x);
  }
  out.pedicel_points = static_cast<int>(pedicel.size());
  if (P.direction_source >= 1 && out.pedicel_points >= P.min_pedicel_points) {
    const Axes a = axes_of(pedicel);
    if (a.values[2] > 4e-6 && a.values[2] > 6.0 * a.values[1]) return along(a.vectors.col(2), mode);  // a line >= 2 mm
  }
  if (P.direction_source >= 1 && static_cast<int>(calyx.size()) >= P.min_points) {
    const Axes a = axes_of(calyx);
    if (a.values[0] < 0.25 * a.values[1]) return along(a.vectors.col(0), mode);  // a disc
  }
  return mode;
}

// Where the seen pedicel crosses the cut distance: the mean of its points there.
void seen_cut_point(const std::vector<Candidate>& c, const Sphere& s, double cut_distance_m, double cos_win,
                    const PedicelEvidenceParams& P, PedicelSighting& out) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& x : c) {
    if (x.dir.dot(out.direction) < cos_win) continue;
    if (std::abs((x.p - s.centre).norm() - cut_distance_m) > P.cut_band_m) continue;
    sum += x.p;
    ++n;
  }
  if (n < 2) return;
  out.cut_point_seen = true;
  out.cut_point = sum / n;
}

}  // namespace

common::Validation validate(const PedicelEvidenceParams& p) {
  if (p.green_margin < 0 || p.min_intensity < 0) return common::Validation::invalid("green_margin, min_intensity >= 0");
  if (!(p.shell_inner_m >= 0) || !(p.shell_outer_m > 0) || !(p.calyx_depth_m >= 0) || !(p.rod_radius_m >= 0) ||
      !(p.cut_band_m > 0))
    return common::Validation::invalid("shell, calyx, rod and band distances must be >= 0 (outer, band > 0)");
  if (!(p.max_prior_angle_deg > 0 && p.max_prior_angle_deg <= 180) || !(p.cone_deg > 0 && p.cone_deg < 90))
    return common::Validation::invalid("max_prior_angle_deg in (0, 180], cone_deg in (0, 90)");
  if (p.min_points < 1 || p.min_pedicel_points < 1) return common::Validation::invalid("min points >= 1");
  if (!(p.calyx_cone_deg > 0 && p.calyx_cone_deg < 90) || !(p.line_reach_m > 0) || p.direction_source < 0 ||
      p.direction_source > 1)
    return common::Validation::invalid("calyx_cone_deg in (0, 90), line_reach_m > 0, direction_source 0 or 1");
  if (!(p.kappa_per_point > 0) || !(p.kappa_max > 0) || !std::isfinite(p.kappa_max))
    return common::Validation::invalid("kappa_per_point and kappa_max must be finite and > 0");
  return common::Validation::ok();
}

bool is_green(const Rgb& c, const PedicelEvidenceParams& p) {
  const int r = c[0], g = c[1], b = c[2];
  return g >= r + p.green_margin && g >= b + p.green_margin && r + g + b >= 3 * p.min_intensity;
}

PedicelSighting sight_pedicel(const GreenPoints& green, const std::vector<Sphere>& spheres, int index,
                              const Eigen::Vector3d& prior_dir, double cut_distance_m, const PedicelEvidenceParams& P) {
  PedicelSighting out;
  if (index < 0 || static_cast<std::size_t>(index) >= spheres.size() || green.xyz.size() != green.view.size())
    return out;
  const std::vector<Candidate> c = shell_points(green, spheres, index, prior_dir.normalized(), P);
  if (static_cast<int>(c.size()) < P.min_points) return out;
  const double cos_win = std::cos(P.cone_deg * kDeg);
  // Wide first (a pedicel far from the prior is still found), then narrow.
  const Eigen::Vector3d wide = mode_direction(c, prior_dir.normalized(), std::cos(P.max_prior_angle_deg * kDeg));
  const Eigen::Vector3d mode = mode_direction(c, wide, cos_win);
  for (const auto& x : c) out.points += x.dir.dot(mode) >= cos_win;
  if (out.points < P.min_points) return out;
  out.direction = seen_direction(c, mode, P, out);
  out.seen = true;
  out.kappa = std::min(P.kappa_max, P.kappa_per_point * out.points);
  seen_cut_point(c, spheres[static_cast<std::size_t>(index)], cut_distance_m, cos_win, P, out);
  return out;
}

PedicelEstimate pedicel_posterior(const PedicelEstimate& prior, const PedicelSighting& s,
                                  const Eigen::Vector3d& gravity) {
  const auto& draws = prior.distribution.draws();
  if (!s.seen || draws.empty()) return prior;
  const double kp = prior.distribution.kappa(), ko = s.kappa;
  // Each prior component times the likelihood: vMF(kp mu_i + ko m), weight
  // C(kp) C(ko) / C(|.|) e^{|.| - kp - ko} (kp = 0: the likelihood at mu_i).
  std::vector<Eigen::Vector3d> centres;
  std::vector<double> logw, kn;
  for (const auto& mu : draws) {
    const Eigen::Vector3d v = kp * mu + ko * s.direction;
    const double n = v.norm();
    centres.push_back(n > 1e-12 ? Eigen::Vector3d(v / n) : mu);
    kn.push_back(n);
    logw.push_back(kp > 0 ? log_vmf_constant(kp) + log_vmf_constant(ko) - log_vmf_constant(n) + n - kp - ko
                          : ko * (mu.dot(s.direction) - 1.0));
  }
  const double top = *std::max_element(logw.begin(), logw.end());
  std::vector<double> cum(logw.size());
  double total = 0, kappa_mean = 0;
  for (std::size_t i = 0; i < logw.size(); ++i) {
    const double w = std::exp(logw[i] - top);
    total += w;
    kappa_mean += w * kn[i];
    cum[i] = total;
  }
  // Systematic resampling: as many draws as the prior had, by weight.
  std::vector<Eigen::Vector3d> post;
  post.reserve(draws.size());
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < draws.size(); ++k) {
    const double u = (static_cast<double>(k) + 0.5) / static_cast<double>(draws.size()) * total;
    const std::size_t i = static_cast<std::size_t>(std::lower_bound(cum.begin(), cum.end(), u) - cum.begin());
    post.push_back(centres[std::min(i, centres.size() - 1)]);
    mean += post.back();
  }
  PedicelEstimate out = prior;
  out.expected_dir = mean.norm() > 1e-12 ? Eigen::Vector3d(mean.normalized()) : s.direction;
  out.expected_force = prior.expected_force.norm() * out.expected_dir;
  out.distribution = PedicelDistribution(std::move(post), kp > 0 ? kappa_mean / total : 0.0, 0x5eedULL + s.points);
  const auto [s50, s90] = spread_deg(out.distribution, out.expected_dir, static_cast<int>(draws.size()), 0x5eedULL);
  out.spread50_deg = s50;
  out.spread90_deg = s90;
  const Eigen::Vector3d up = -gravity.normalized();
  out.gravity_angle_rad = std::atan2(out.expected_dir.cross(up).norm(), out.expected_dir.dot(up));
  return out;
}

}  // namespace tinyline::tomato_reasoning
