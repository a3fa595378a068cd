// SPDX-License-Identifier: Apache-2.0
// Elastic rods, rigid fruit and frictional contacts, settled by FIRE (see
// scenes/truss_rod.hpp).
#include <sim/scenes/truss_rod.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

namespace tinyline::sim::rod {

namespace {

using Vec = Eigen::Vector3d;
using Forces = std::vector<Vec>;

Vec unit(const Vec& e) { return e / e.norm(); }

// d u / d x_b applied to g, for u = (x_b - x_a) / |x_b - x_a|.
Vec direction_gradient(const Vec& e, const Vec& g) {
  const double l = e.norm();
  const Vec u = e / l;
  return (g - u.dot(g) * u) / l;
}

void add_elastic(const Network& n, Forces& f) {
  for (const auto& s : n.segments) {
    const Vec e = n.x[std::size_t(s.b)] - n.x[std::size_t(s.a)];
    const double l = e.norm();
    const Vec t = s.axial_n * (l - s.rest_m) / s.rest_m * (e / l);
    f[std::size_t(s.a)] += t;
    f[std::size_t(s.b)] -= t;
  }
  for (const auto& h : n.hinges) {
    const Vec e1 = n.x[std::size_t(h.b1)] - n.x[std::size_t(h.a1)],
              e2 = n.x[std::size_t(h.b2)] - n.x[std::size_t(h.a2)];
    const Vec g = h.k_nm * (unit(e2) - unit(e1) - h.rest);  // dE / d(u2 - u1)
    const Vec g2 = direction_gradient(e2, g), g1 = direction_gradient(e1, g);
    f[std::size_t(h.b2)] -= g2;
    f[std::size_t(h.a2)] += g2;
    f[std::size_t(h.b1)] += g1;
    f[std::size_t(h.a1)] -= g1;
  }
  for (const auto& t : n.ties) {
    const Vec r = n.x[std::size_t(t.q)] - ((1 - t.w) * n.x[std::size_t(t.a)] + t.w * n.x[std::size_t(t.b)] + t.offset);
    f[std::size_t(t.q)] -= t.k_n_m * r;
    f[std::size_t(t.a)] += (1 - t.w) * t.k_n_m * r;
    f[std::size_t(t.b)] += t.w * t.k_n_m * r;
  }
}

void add_gravity(const Network& n, double g, Forces& f) {
  for (std::size_t i = 0; i < n.x.size(); ++i) f[i].z() -= n.lumped_mass_kg[i] * g;
  for (const auto& b : n.bodies) f[std::size_t(b.node)].z() -= b.mass_kg * g;
}

// One touch: body i against body j or against the closest segment of a rod.
struct Touch {
  int body = -1;
  ContactWith with = ContactWith::kBody;
  int other = -1;
  int a = -1, b = -1;  // the other's nodes (b = -1: a body's node)
  double t = 0.0;      // where on a-b
  double gap = 0.0;
  Vec n;  // unit, pushes the body away
};

std::vector<Touch> touches(const Network& net) {
  std::vector<Touch> out;
  const auto& B = net.bodies;
  for (std::size_t i = 0; i < B.size(); ++i) {
    const Vec ci = net.x[std::size_t(B[i].node)];
    for (std::size_t j = i + 1; j < B.size(); ++j) {
      const Vec v = ci - net.x[std::size_t(B[j].node)];
      const double d = v.norm(), gap = d - B[i].radius_m - B[j].radius_m;
      if (gap < 0 && d > 1e-12) out.push_back({int(i), ContactWith::kBody, int(j), B[j].node, -1, 0.0, gap, v / d});
    }
    std::map<int, Touch> best;  // per rod: its deepest segment
    for (const auto& s : net.tubes) {
      if (s.rod == B[i].rod) continue;
      const Vec pa = net.x[std::size_t(s.a)], ab = net.x[std::size_t(s.b)] - pa;
      const double t = std::clamp((ci - pa).dot(ab) / std::max(ab.squaredNorm(), 1e-18), 0.0, 1.0);
      const Vec v = ci - (pa + t * ab);
      const double d = v.norm(), gap = d - B[i].radius_m - s.radius_m;
      if (gap >= 0 || d < 1e-12) continue;
      auto it = best.find(s.rod);
      if (it == best.end() || gap < it->second.gap)
        best[s.rod] = {int(i), ContactWith::kTube, s.rod, s.a, s.b, t, gap, v / d};
    }
    for (const auto& [rod, t] : best) out.push_back(t);
  }
  return out;
}

using ContactKey = std::tuple<int, int, int>;  // body, kind, other

// Penalty contacts with Cundall-Strack friction; `slip` keeps each
// contact's tangential spring between calls.
class ContactLaw {
 public:
  ContactLaw(double k, double mu) : k_(k), mu_(mu) {}

  std::vector<Contact> apply(const Network& net, const std::vector<Vec>& prev, Forces& f) {
    std::vector<Contact> out;
    std::map<ContactKey, Vec> next;
    for (const Touch& t : touches(net)) {
      const ContactKey key{t.body, int(t.with), t.other};
      Vec xi = Vec::Zero();
      if (auto it = slip_.find(key); it != slip_.end()) xi = it->second;
      const int ni = net.bodies[std::size_t(t.body)].node;
      Vec moved = net.x[std::size_t(ni)] - prev[std::size_t(ni)];
      moved -= other_moved(net, prev, t);
      xi += moved;
      xi -= xi.dot(t.n) * t.n;  // keep it in the current tangent plane
      const double fn = k_ * -t.gap;
      if (k_ * xi.norm() > mu_ * fn) xi *= mu_ * fn / (k_ * xi.norm());
      next[key] = xi;
      const Vec F = fn * t.n - k_ * xi;
      f[std::size_t(ni)] += F;
      distribute_to_other(t, -F, f);
      out.push_back({t.body, t.with, t.other, fn, k_ * xi.norm(), F, -t.gap});
    }
    slip_ = std::move(next);  // contacts that opened forget their spring
    return out;
  }

 private:
  static Vec other_moved(const Network& net, const std::vector<Vec>& prev, const Touch& t) {
    const auto d = [&](int k) { return Vec(net.x[std::size_t(k)] - prev[std::size_t(k)]); };
    return t.b < 0 ? d(t.a) : Vec((1 - t.t) * d(t.a) + t.t * d(t.b));
  }
  static void distribute_to_other(const Touch& t, const Vec& F, Forces& f) {
    if (t.b < 0) {
      f[std::size_t(t.a)] += F;
    } else {
      f[std::size_t(t.a)] += (1 - t.t) * F;
      f[std::size_t(t.b)] += t.t * F;
    }
  }
  double k_, mu_;
  std::map<ContactKey, Vec> slip_;
};

// Fictitious masses: a Gershgorin bound of each node's stiffness, so that a
// unit step of the explicit integrator is stable (contacts: an allowance of
// four touches per fruit, two per rod node).
std::vector<double> fictitious_masses(const Network& n, double k_contact) {
  std::vector<double> m(n.x.size(), 0.0);
  for (const auto& s : n.segments) {
    m[std::size_t(s.a)] += 2 * s.axial_n / s.rest_m;
    m[std::size_t(s.b)] += 2 * s.axial_n / s.rest_m;
  }
  for (const auto& h : n.hinges) {
    const double s = 1.0 / (n.x[std::size_t(h.b1)] - n.x[std::size_t(h.a1)]).norm() +
                     1.0 / (n.x[std::size_t(h.b2)] - n.x[std::size_t(h.a2)]).norm();
    for (int k : {h.a1, h.b1, h.a2, h.b2}) m[std::size_t(k)] += 3 * h.k_nm * s * s;
  }
  for (const auto& t : n.ties)
    for (int k : {t.q, t.a, t.b}) m[std::size_t(k)] += 2 * t.k_n_m;
  for (const auto& b : n.bodies) m[std::size_t(b.node)] += 8 * k_contact;
  for (const auto& t : n.tubes)
    for (int k : {t.a, t.b}) m[std::size_t(k)] += 4 * k_contact;
  for (auto& v : m) v = std::max(v, 1e-6);
  return m;
}

double max_free_force(const Network& n, const Forces& f) {
  double r = 0.0;
  for (std::size_t i = 0; i < f.size(); ++i)
    if (!n.fixed[i]) r = std::max(r, f[i].norm());
  return r;
}

// FIRE's velocity mixing in mass-scaled coordinates; false when the power
// turned negative and the velocities were reset.
struct Fire {
  double dt = 0.1, alpha = 0.1;
  int positive = 0;
  bool mix(const Network& n, const Forces& f, const std::vector<double>& m, std::vector<Vec>& v) {
    double power = 0.0, vv = 0.0, ff = 0.0;
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (n.fixed[i]) continue;
      power += f[i].dot(v[i]);
      vv += m[i] * v[i].squaredNorm();
      ff += f[i].squaredNorm() / m[i];
    }
    if (power <= 0.0) {
      for (auto& x : v) x.setZero();
      dt *= 0.5;
      alpha = 0.1;
      positive = 0;
      return false;
    }
    const double scale = ff > 0 ? std::sqrt(vv / ff) : 0.0;
    for (std::size_t i = 0; i < f.size(); ++i) v[i] = (1 - alpha) * v[i] + alpha * scale * f[i] / m[i];
    if (++positive > 5) {
      dt = std::min(dt * 1.1, 1.0);
      alpha *= 0.99;
    }
    return true;
  }
};

}  // namespace

int Network::add_node(const Eigen::Vector3d& p, bool is_fixed) {
  x.push_back(p);
  fixed.push_back(is_fixed ? 1 : 0);
  lumped_mass_kg.push_back(0.0);
  return int(x.size()) - 1;
}

void Network::add_segment(int a, int b, double axial_n) {
  segments.push_back({a, b, (x[std::size_t(b)] - x[std::size_t(a)]).norm(), axial_n});
}

void Network::add_hinge(int a1, int b1, int a2, int b2, double k_nm) {
  const Vec rest = unit(x[std::size_t(b2)] - x[std::size_t(a2)]) - unit(x[std::size_t(b1)] - x[std::size_t(a1)]);
  hinges.push_back({a1, b1, a2, b2, k_nm, rest});
}

double round_section_inertia(double radius_m) { return M_PI * std::pow(radius_m, 4) / 4.0; }

SettleReport settle(Network& net, const SettleOptions& o) {
  SettleReport rep;
  const std::size_t n = net.x.size();
  const std::vector<double> m = fictitious_masses(net, o.contact_stiffness_n_m);
  ContactLaw law(o.contact_stiffness_n_m, o.friction);
  std::vector<Vec> v(n, Vec::Zero()), prev = net.x;
  Fire fire;
  Forces f(n);
  auto forces = [&]() {
    std::fill(f.begin(), f.end(), Vec::Zero());
    add_elastic(net, f);
    add_gravity(net, o.gravity_m_s2, f);
    rep.contacts = law.apply(net, prev, f);
    prev = net.x;
  };
  forces();
  for (rep.iterations = 0; rep.iterations < o.max_iterations; ++rep.iterations) {
    rep.max_residual_n = max_free_force(net, f);
    if (rep.max_residual_n < o.tolerance_n) break;
    fire.mix(net, f, m, v);
    for (std::size_t i = 0; i < n; ++i) {
      if (net.fixed[i]) continue;
      v[i] += fire.dt * f[i] / m[i];
      net.x[i] += fire.dt * v[i];
    }
    forces();
  }
  rep.max_residual_n = max_free_force(net, f);
  rep.converged = rep.max_residual_n < o.tolerance_n;
  for (const auto& c : rep.contacts) rep.max_penetration_m = std::max(rep.max_penetration_m, c.penetration_m);
  return rep;
}

}  // namespace tinyline::sim::rod
