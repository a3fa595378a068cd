// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/reasoning.hpp"

#include "tomato_reasoning/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

#include <Eigen/Geometry>

#include <tinyline/common/random.hpp>

namespace tinyline::tomato_reasoning {

namespace {

constexpr double kRefRadius = 0.03;  // [m] weights are relative to a 3 cm tomato

double normal_pdf(double x) { return std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI); }
double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// Any unit vector orthogonal to unit n, and a third completing the frame.
void frame_of(const Eigen::Vector3d& n, Eigen::Vector3d& e1, Eigen::Vector3d& e2) {
  e1 = n.unitOrthogonal();
  e2 = n.cross(e1);
}

// A direction around unit mu: von Mises-Fisher with concentration kappa
// (Wood 1994, exact on S^2), or uniform in the cap of half angle `cap_rad`
// when kappa = 0 (the top-hat kernel of a binned density).
Eigen::Vector3d draw_around(const Eigen::Vector3d& mu, double kappa, double cap_rad, common::SplitMixRandom& rng) {
  double w;
  if (kappa > 0) {
    const double xi = rng.uniform_open();
    w = 1.0 + std::log(xi + (1.0 - xi) * std::exp(-2.0 * kappa)) / kappa;
  } else {
    const double c = std::cos(cap_rad);
    w = c + (1.0 - c) * rng.uniform_open();
  }
  w = std::clamp(w, -1.0, 1.0);
  const double phi = 2.0 * M_PI * rng.uniform_open();
  Eigen::Vector3d e1, e2;
  frame_of(mu, e1, e2);
  return (w * mu + std::sqrt(1.0 - w * w) * (std::cos(phi) * e1 + std::sin(phi) * e2)).normalized();
}

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

}  // namespace

std::vector<ContactEdge> contact_graph(const std::vector<Sphere>& s, double d_e_m) {
  std::vector<ContactEdge> out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (std::size_t j = i + 1; j < s.size(); ++j) {
      const double gap = (s[i].centre - s[j].centre).norm() - (s[i].radius_m + s[j].radius_m);
      if (std::abs(gap) <= d_e_m) out.push_back({static_cast<int>(i), static_cast<int>(j), gap});  // Eq. 4.17
    }
  }
  return out;
}

common::Status validate(const ForceModelParams& p) {
  if (common::Status s = common::within_table(p); !s.ok()) return s;
  if (normal_cdf((p.eps_max - p.eps_mean) / std::sqrt(p.eps_variance)) -
          normal_cdf(-p.eps_mean / std::sqrt(p.eps_variance)) <
      1e-6)
    return common::Status::invalid("eps ~ N(eps_mean, eps_variance) has (almost) no mass in [0, eps_max)");
  return {};
}

double truncated_normal_mean(double mu, double var, double max) {
  const double sd = std::sqrt(var);
  const double a = (0.0 - mu) / sd, b = (max - mu) / sd;
  const double z = normal_cdf(b) - normal_cdf(a);
  if (!(z > 0)) return std::clamp(mu, 0.0, max);
  return mu + sd * (normal_pdf(a) - normal_pdf(b)) / z;
}

PedicelDistribution::PedicelDistribution(std::vector<Eigen::Vector3d> draws, double kappa, std::uint64_t seed)
    : draws_(std::move(draws)), kappa_(kappa), seed_(seed) {}

double PedicelDistribution::density(const Eigen::Vector3d& d, double cell_deg) const {
  if (draws_.empty()) return 0.0;
  double s = 0;
  if (kappa_ > 0) {
    // vMF on S^2: C(kappa) exp(kappa (mu . x - 1)), C = kappa / (2 pi (1 - e^{-2 kappa})).
    const double c = kappa_ / (2.0 * M_PI * (1.0 - std::exp(-2.0 * kappa_)));
    for (const auto& m : draws_) s += c * std::exp(kappa_ * (m.dot(d) - 1.0));
  } else {
    // Top-hat: the share of draws within half a cell, over the cap's solid angle.
    const double rho = 0.5 * cell_deg * M_PI / 180.0;
    const double cos_rho = std::cos(rho);
    int n = 0;
    for (const auto& m : draws_) n += m.dot(d) >= cos_rho;
    s = n / (2.0 * M_PI * (1.0 - cos_rho));
  }
  return s / static_cast<double>(draws_.size());
}

std::vector<Eigen::Vector3d> PedicelDistribution::sample(int n, std::uint64_t seed) const {
  std::vector<Eigen::Vector3d> out;
  if (draws_.empty() || n <= 0) return out;
  common::SplitMixRandom rng(common::stream_seed(seed, 0x632be59bd9b4e019ULL));
  const double cap = 2.5 * M_PI / 180.0;  // half of the default 5 deg cell
  out.reserve(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) out.push_back(draw_around(draws_[rng.index(draws_.size())], kappa_, cap, rng));
  return out;
}

double PedicelDistribution::hpd_level(double mass, int n, double cell_deg) const {
  // HPD region {d : p(d) >= t} holds `mass` when P(p(D) >= t) = mass, D ~ p:
  // t is the (1 - mass) quantile of the density at draws of the distribution.
  const auto xs = sample(n, seed_ ^ 0xa11ce5eedULL);
  if (xs.empty()) return 0.0;
  std::vector<double> p;
  p.reserve(xs.size());
  for (const auto& x : xs) p.push_back(density(x, cell_deg));
  const std::size_t k =
      std::min(p.size() - 1, static_cast<std::size_t>(std::floor((1.0 - mass) * static_cast<double>(p.size()))));
  std::nth_element(p.begin(), p.begin() + static_cast<std::ptrdiff_t>(k), p.end());
  return p[k];
}

bool PedicelDistribution::in_hpd(const Eigen::Vector3d& d, double mass, int n, double cell_deg) const {
  return density(d.normalized(), cell_deg) >= hpd_level(mass, n, cell_deg);
}

std::vector<std::vector<double>> PedicelDistribution::grid(int n_phi, int n_theta, double cell_deg) const {
  std::vector<std::vector<double>> g(static_cast<std::size_t>(n_theta),
                                     std::vector<double>(static_cast<std::size_t>(n_phi)));
  for (int t = 0; t < n_theta; ++t) {
    const double theta = (t + 0.5) * M_PI / n_theta;
    for (int f = 0; f < n_phi; ++f) {
      const double phi = -M_PI + (f + 0.5) * 2.0 * M_PI / n_phi;
      const Eigen::Vector3d d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      g[static_cast<std::size_t>(t)][static_cast<std::size_t>(f)] = density(d, cell_deg);
    }
  }
  return g;
}

PedicelDistribution PedicelDistribution::rotated(const Eigen::Matrix3d& R) const {
  std::vector<Eigen::Vector3d> d;
  d.reserve(draws_.size());
  for (const auto& x : draws_) d.push_back((R * x).normalized());
  return PedicelDistribution(std::move(d), kappa_, seed_);
}

std::pair<double, double> spread_deg(const PedicelDistribution& d, const Eigen::Vector3d& centre, int n,
                                     std::uint64_t seed) {
  // Angles of the full distribution (kernel included) from `centre`.
  std::vector<double> ang;
  for (const auto& x : d.sample(n, seed)) ang.push_back(angle_between(x, centre));
  if (ang.empty()) return {0.0, 0.0};
  std::sort(ang.begin(), ang.end());
  return {ang[ang.size() / 2] * 180.0 / M_PI, ang[std::min(ang.size() - 1, ang.size() * 9 / 10)] * 180.0 / M_PI};
}

std::vector<PedicelEstimate> estimate_pedicels(const std::vector<Sphere>& spheres,
                                               const std::vector<ContactEdge>& edges, const Eigen::Vector3d& gravity,
                                               const ForceModelParams& P) {
  std::vector<PedicelEstimate> out;
  if (!validate(P).ok() || spheres.empty() || !(gravity.norm() > 0) || !gravity.allFinite()) return out;
  const Eigen::Vector3d g = gravity.normalized();
  const double sd = std::sqrt(P.eps_variance);
  const double eps_mean = truncated_normal_mean(P.eps_mean, P.eps_variance, P.eps_max);
  auto weight = [&](double r) {
    return kRefRadius * std::pow(r / kRefRadius, P.weight_exponent);
  };  // theta r for exponent 1
  common::SplitMixRandom rng(common::stream_seed(P.seed, 0x632be59bd9b4e019ULL));
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    PedicelEstimate e;
    e.sphere = static_cast<int>(i);
    // Neighbours push along the line of centres, towards i.
    std::vector<Eigen::Vector3d> push;
    std::vector<double> w_edge;
    for (const auto& ed : edges) {
      if (ed.i != static_cast<int>(i) && ed.j != static_cast<int>(i)) continue;
      const int j = ed.i == static_cast<int>(i) ? ed.j : ed.i;
      const Eigen::Vector3d u = spheres[i].centre - spheres[static_cast<std::size_t>(j)].centre;
      if (!(u.norm() > 1e-9)) continue;
      push.push_back(u.normalized());
      w_edge.push_back(0.5 * (weight(spheres[i].radius_m) + weight(spheres[static_cast<std::size_t>(j)].radius_m)));
    }
    e.edges = static_cast<int>(push.size());
    const Eigen::Vector3d G = weight(spheres[i].radius_m) * g;
    // Eq. 4.22 in expectation.
    Eigen::Vector3d Ft = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < push.size(); ++k) Ft += eps_mean * w_edge[k] * push[k];
    e.expected_force = -(G + Ft);
    e.expected_dir = e.expected_force.norm() > 1e-12 ? e.expected_force.normalized() : Eigen::Vector3d(-g);
    // Draws of eps per edge (Eq. 4.19 by rejection from the untruncated normal).
    std::vector<Eigen::Vector3d> draws;
    draws.reserve(static_cast<std::size_t>(P.samples));
    for (int s = 0; s < P.samples; ++s) {
      Eigen::Vector3d F = G;
      for (std::size_t k = 0; k < push.size(); ++k) {
        double eps;
        do {
          eps = P.eps_mean + sd * rng.normal_unpaired();
        } while (!(eps >= 0.0 && eps < P.eps_max));
        F += eps * w_edge[k] * push[k];  // Eq. 4.20, 4.21
      }
      const Eigen::Vector3d Fp = -F;  // Eq. 4.22
      draws.push_back(Fp.norm() > 1e-12 ? Eigen::Vector3d(Fp.normalized()) : e.expected_dir);
    }
    e.distribution = PedicelDistribution(std::move(draws), P.kernel_kappa, P.seed * 1000003ULL + i);
    std::tie(e.spread50_deg, e.spread90_deg) =
        spread_deg(e.distribution, e.expected_dir, P.samples, P.seed + 7 * i + 1);
    e.gravity_angle_rad = angle_between(e.expected_dir, -g);
    out.push_back(std::move(e));
  }
  return out;
}

namespace {
// N of Eq. 4.23 for sphere i: each neighbour counted by how surely it touches.
double soft_edges(const std::vector<Sphere>& spheres, std::size_t i, double d_e, double soft) {
  double n = 0;
  for (std::size_t j = 0; j < spheres.size(); ++j) {
    if (j == i) continue;
    const double gap = (spheres[i].centre - spheres[j].centre).norm() - spheres[i].radius_m - spheres[j].radius_m;
    n += std::clamp((d_e + soft - std::abs(gap)) / (2 * soft), 0.0, 1.0);
  }
  return n;
}

}  // namespace

std::vector<PickCost> pick_order(const std::vector<Sphere>& spheres, const std::vector<PedicelEstimate>& pedicels,
                                 const Eigen::Vector3d& gravity, const PickOrderParams& P, double d_e) {
  std::vector<PickCost> out;
  if (spheres.empty() || pedicels.size() != spheres.size() || !(gravity.norm() > 0)) return out;
  const Eigen::Vector3d g = gravity.normalized();
  double lowest = std::numeric_limits<double>::infinity();
  for (const auto& s : spheres) lowest = std::min(lowest, -s.centre.dot(g));
  for (std::size_t i = 0; i < spheres.size(); ++i) {
    PickCost c;
    c.sphere = static_cast<int>(i);
    const double height = -spheres[i].centre.dot(g) - lowest;
    const double Ep = spheres[i].radius_m / kRefRadius * height;  // theta r h, theta per 3 cm tomato
    const double N = P.edge_softness_m > 0 ? soft_edges(spheres, i, d_e, P.edge_softness_m) : pedicels[i].edges;
    c.energy_term = -P.w_energy_per_m * Ep;                            // Eq. 4.23: -Ep
    c.edge_term = P.w_edges * N;                                       // N
    c.angle_term = P.w_angle_per_rad * pedicels[i].gravity_angle_rad;  // <F^e_ip, -G_i>
    c.cost = c.energy_term + c.edge_term + c.angle_term;
    out.push_back(c);
  }
  std::stable_sort(out.begin(), out.end(), [](const PickCost& a, const PickCost& b) { return a.cost < b.cost; });
  return out;
}

CutPlan plan_cut(const std::vector<Sphere>& spheres, int index, const PedicelEstimate& ped, const CutParams& P) {
  CutPlan plan;
  if (index < 0 || static_cast<std::size_t>(index) >= spheres.size()) return plan;
  const Sphere& s = spheres[static_cast<std::size_t>(index)];
  const double arm = s.radius_m + P.cut_offset_m;
  plan.half_angle_rad = std::atan2(0.5 * P.scissor_opening_m, arm);
  const double cos_half = std::cos(plan.half_angle_rad);
  const auto eval = ped.distribution.sample(400, 0xc0ffeeULL + static_cast<std::uint64_t>(index));
  auto coverage = [&](const Eigen::Vector3d& u) {
    int n = 0;
    for (const auto& d : eval) n += d.dot(u) >= cos_half;
    return eval.empty() ? 0.0 : n / static_cast<double>(eval.size());
  };
  auto blocked = [&](const Eigen::Vector3d& u) {
    const Eigen::Vector3d q = s.centre + arm * u;
    for (std::size_t j = 0; j < spheres.size(); ++j)
      if (static_cast<int>(j) != index && (q - spheres[j].centre).norm() < spheres[j].radius_m) return true;
    return false;
  };
  std::vector<Eigen::Vector3d> cands =
      ped.distribution.sample(P.candidates, 0xca7ULL + static_cast<std::uint64_t>(index));
  cands.insert(cands.begin(), ped.expected_dir);
  double best = -1;
  bool any_free = false;
  for (const auto& u : cands) {
    const bool b = blocked(u);
    if (any_free && b) continue;
    const double c = coverage(u);
    // A free cut beats any blocked one; then more coverage; ties keep the earlier (the expectation first).
    if ((!b && !any_free) || c > best) {
      if (!b) any_free = true;
      best = c;
      plan.direction = u;
    }
  }
  plan.blocked = !any_free;
  plan.coverage = std::max(0.0, best);
  plan.expected_coverage = coverage(ped.expected_dir);
  plan.point = s.centre + arm * plan.direction;
  return plan;
}

}  // namespace tinyline::tomato_reasoning
