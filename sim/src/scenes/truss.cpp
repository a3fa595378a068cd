// SPDX-License-Identifier: Apache-2.0
// Generator "truss": tomato trusses in static equilibrium (see scenes/truss.hpp).
#include <sim/scenes/truss.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <sim/rgbd_camera.hpp>
#include <sim/scenes/truss_rod.hpp>
#include <tinyline/common/random.hpp>

namespace tinyline::sim {

namespace {

constexpr double kG = 9.81;  // [m/s^2]

// The truss's draws: uniforms in (0, 1] on the common splitmix64 stream
// (a fixed sequence per seed on every platform).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : r_(common::stream_seed(seed, 0x7f4a7c159e3779b9ULL)) {}
  double uniform() { return r_.uniform_open(); }
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  int integer(int lo, int hi) { return lo + static_cast<int>(uniform() * (hi - lo + 1)); }  // [lo, hi]
  double normal() { return r_.normal_unpaired(); }
  bool chance(double p) { return uniform() < p; }

 private:
  common::SplitMixRandom r_;
};

// Closest point parameter of p on segment a-b, in [0, 1].
double closest_t(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double l2 = ab.squaredNorm();
  if (l2 < 1e-18) return 0.0;
  return std::clamp((p - a).dot(ab) / l2, 0.0, 1.0);
}

// A direction tilted `tilt` rad from straight down towards azimuth `az`.
Eigen::Vector3d down_tilted(double tilt, double az) {
  return {std::sin(tilt) * std::cos(az), std::sin(tilt) * std::sin(az), -std::cos(tilt)};
}

struct Pendulum {
  Eigen::Vector3d anchor;
  double pedicel_m = 0.0;  // anchor to calyx
  double radius_m = 0.0;   // bounding radius: what contacts see
  double polar_m = 0.0;    // centre to calyx
  double mass_kg = 0.0;
  double stiffness = 0.0;  // [N m / rad]
  Eigen::Vector3d rest;    // unit
  Eigen::Vector3d d;       // unit, anchor -> centre
  // Shape (see TrussTomato).
  double r_eq = 0.0, equatorial = 0.0, rib = 0.0, rib_phase = 0.0;
  int lobes = 5;
  // Set by the elastic-rod settle, whose centre is off the anchor -> d line
  // when the pedicel curves.
  std::optional<Eigen::Vector3d> rod_centre;
  double arm() const { return pedicel_m + polar_m; }
  Eigen::Vector3d centre() const { return rod_centre ? *rod_centre : Eigen::Vector3d(anchor + arm() * d); }
  Eigen::Vector3d calyx() const { return anchor + pedicel_m * d; }
};

struct Segment {
  Eigen::Vector3d a, b;
  double radius_m;
};

// One non-penetration constraint at the rest state: tomato i against
// tomato j, against the peduncle (j = -1), or against the pedicel of j at
// lever ratio `lever` (where along j's arm it is touched, 0 at the anchor).
struct Constraint {
  int i = -1, j = -1;
  bool pedicel = false;
  double lever = 1.0;
  double gap = 0.0;   // distance minus contact distance [m] (< 0: overlap)
  Eigen::Vector3d n;  // unit, pushes i away from the other body
};

std::vector<Constraint> constraints(const std::vector<Pendulum>& p, const std::vector<Segment>& peduncle,
                                    double pedicel_radius, double reach) {
  std::vector<Constraint> out;
  const std::size_t n = p.size();
  std::vector<Eigen::Vector3d> c(n);
  for (std::size_t i = 0; i < n; ++i) c[i] = p[i].centre();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      const Eigen::Vector3d v = c[i] - c[j];
      const double dist = v.norm();
      const double gap = dist - p[i].radius_m - p[j].radius_m;
      if (gap < reach && dist > 1e-12) out.push_back({int(i), int(j), false, 1.0, gap, v / dist});
    }
    // The peduncle holds still (the main stem carries it): keep the deepest touch.
    Constraint best{int(i), -1, false, 1.0, reach, Eigen::Vector3d::UnitZ()};
    for (const auto& s : peduncle) {
      const Eigen::Vector3d q = s.a + closest_t(c[i], s.a, s.b) * (s.b - s.a);
      const Eigen::Vector3d v = c[i] - q;
      const double dist = v.norm();
      const double gap = dist - p[i].radius_m - s.radius_m;
      if (gap < best.gap && dist > 1e-12) best = {int(i), -1, false, 1.0, gap, v / dist};
    }
    if (best.gap < reach) out.push_back(best);
    for (std::size_t j = 0; j < n; ++j) {
      if (i == j) continue;
      const Eigen::Vector3d a = p[j].anchor, b = p[j].calyx();
      const double t = closest_t(c[i], a, b);
      const Eigen::Vector3d v = c[i] - (a + t * (b - a));
      const double dist = v.norm();
      const double gap = dist - p[i].radius_m - pedicel_radius;
      if (gap < reach && dist > 1e-12)
        out.push_back({int(i), int(j), true, t * p[j].pedicel_m / p[j].arm(), gap, v / dist});
    }
  }
  return out;
}

// Gravity and the bending spring, as a force at each centre.
std::vector<Eigen::Vector3d> free_forces(const std::vector<Pendulum>& p) {
  std::vector<Eigen::Vector3d> f(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    f[i] = Eigen::Vector3d(0, 0, -p[i].mass_kg * kG);
    const double cosang = std::clamp(p[i].d.dot(p[i].rest), -1.0, 1.0);
    const double ang = std::acos(cosang);
    if (ang > 1e-9) f[i] += p[i].stiffness * ang / p[i].arm() * (p[i].rest - cosang * p[i].d) / std::sin(ang);
  }
  return f;
}

Eigen::Vector3d tangential(const Pendulum& p, const Eigen::Vector3d& f) { return f - f.dot(p.d) * p.d; }

void move_centre(Pendulum& p, const Eigen::Vector3d& delta) { p.d = (p.centre() + delta - p.anchor).normalized(); }

// Non-negative least squares, min |A x - b| with x >= 0 (Lawson-Hanson).
Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const Eigen::Index m = A.cols();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(m);
  std::vector<bool> passive(static_cast<std::size_t>(m), false);
  for (int outer = 0; outer < 3 * m + 10; ++outer) {
    const Eigen::VectorXd w = A.transpose() * (b - A * x);
    Eigen::Index best = -1;
    double wmax = 1e-12;
    for (Eigen::Index k = 0; k < m; ++k)
      if (!passive[std::size_t(k)] && w[k] > wmax) {
        wmax = w[k];
        best = k;
      }
    if (best < 0) break;
    passive[std::size_t(best)] = true;
    for (int inner = 0; inner < 3 * m + 10; ++inner) {
      std::vector<Eigen::Index> idx;
      for (Eigen::Index k = 0; k < m; ++k)
        if (passive[std::size_t(k)]) idx.push_back(k);
      Eigen::MatrixXd Ap(A.rows(), Eigen::Index(idx.size()));
      for (std::size_t k = 0; k < idx.size(); ++k) Ap.col(Eigen::Index(k)) = A.col(idx[k]);
      const Eigen::VectorXd z = Ap.completeOrthogonalDecomposition().solve(b);
      Eigen::VectorXd s = Eigen::VectorXd::Zero(m);
      for (std::size_t k = 0; k < idx.size(); ++k) s[idx[k]] = z[Eigen::Index(k)];
      bool feasible = true;
      double alpha = 1.0;
      for (Eigen::Index k : idx) {
        if (s[k] <= 0) {
          feasible = false;
          alpha = std::min(alpha, x[k] / std::max(1e-300, x[k] - s[k]));
        }
      }
      if (feasible) {
        x = s;
        break;
      }
      x += alpha * (s - x);
      for (Eigen::Index k : idx)
        if (x[k] <= 1e-15) {
          passive[std::size_t(k)] = false;
          x[k] = 0;
        }
    }
  }
  return x;
}

// The linearised contacts in tangent space: per contact, (tomato,
// coefficient vector) pairs of its Jacobian row.
using JacobianRow = std::array<std::pair<int, Eigen::Vector3d>, 2>;

std::vector<JacobianRow> contact_jacobian(const std::vector<Pendulum>& p, const std::vector<Constraint>& cons) {
  std::vector<JacobianRow> J(cons.size());
  for (std::size_t k = 0; k < cons.size(); ++k) {
    const auto& c = cons[k];
    J[k][0] = {c.i, tangential(p[std::size_t(c.i)], c.n)};
    J[k][1] = {c.j, c.j >= 0 ? Eigen::Vector3d(-(c.pedicel ? c.lever : 1.0) * tangential(p[std::size_t(c.j)], c.n))
                             : Eigen::Vector3d::Zero()};
  }
  return J;
}

// The multipliers of the nearest move to `delta` that keeps every contact
// closed or opening: the small QP's dual (M = J J^T, q = gap + J delta) by
// projected Gauss-Seidel.
std::vector<double> contact_multipliers(const std::vector<JacobianRow>& J, const std::vector<Constraint>& cons,
                                        const std::vector<Eigen::Vector3d>& delta) {
  const std::size_t nc = cons.size();
  const Eigen::Index m = Eigen::Index(nc);
  auto dot_rows = [&](std::size_t a, std::size_t b) {
    double s = 0;
    for (const auto& [ia, va] : J[a])
      for (const auto& [ib, vb] : J[b])
        if (ia >= 0 && ia == ib) s += va.dot(vb);
    return s;
  };
  Eigen::MatrixXd M(m, m);
  for (std::size_t a = 0; a < nc; ++a)
    for (std::size_t b = a; b < nc; ++b)
      M(Eigen::Index(a), Eigen::Index(b)) = M(Eigen::Index(b), Eigen::Index(a)) = dot_rows(a, b);
  Eigen::VectorXd q(m);
  for (std::size_t k = 0; k < nc; ++k) {
    double jd = 0;
    for (const auto& [i, v] : J[k])
      if (i >= 0) jd += v.dot(delta[std::size_t(i)]);
    q[Eigen::Index(k)] = cons[k].gap + jd;
  }
  std::vector<double> mu(nc, 0.0);
  for (int sweep = 0; sweep < 200; ++sweep) {
    double change = 0;
    for (std::size_t k = 0; k < nc; ++k) {
      const double Mkk = M(Eigen::Index(k), Eigen::Index(k));
      if (Mkk < 1e-12) continue;
      double r = q[Eigen::Index(k)];
      for (std::size_t l = 0; l < nc; ++l) r += M(Eigen::Index(k), Eigen::Index(l)) * mu[l];
      const double nv = std::max(0.0, mu[k] - r / Mkk);
      change = std::max(change, std::abs(nv - mu[k]));
      mu[k] = nv;
    }
    if (change < 1e-12) break;
  }
  return mu;
}

// One projected step along the free forces; returns the largest move [m].
double relax_step(std::vector<Pendulum>& p, const std::vector<Segment>& peduncle, double pedicel_radius, double step) {
  const std::size_t n = p.size();
  const auto cons = constraints(p, peduncle, pedicel_radius, 0.01);
  const auto f = free_forces(p);
  std::vector<Eigen::Vector3d> delta(n);
  for (std::size_t i = 0; i < n; ++i) delta[i] = step * tangential(p[i], f[i]);
  const auto J = contact_jacobian(p, cons);
  const auto mu = contact_multipliers(J, cons, delta);
  for (std::size_t k = 0; k < cons.size(); ++k)
    for (const auto& [i, v] : J[k])
      if (i >= 0) delta[std::size_t(i)] += mu[k] * v;
  double moved = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    move_centre(p[i], delta[i]);
    moved = std::max(moved, delta[i].norm());
  }
  return moved;
}

// Contact forces from the balance of every pendulum at rest (tangential
// parts, non-negative least squares); fills the report's residual and
// penetration.
void balance_contacts(const std::vector<Pendulum>& p, const std::vector<Segment>& peduncle, double pedicel_radius,
                      std::vector<TrussContact>& contacts, std::vector<Eigen::Vector3d>& contact_force,
                      RelaxationReport& rep) {
  const std::size_t n = p.size();
  const auto active = constraints(p, peduncle, pedicel_radius, 2e-4);
  const auto f = free_forces(p);
  const Eigen::Index rows = Eigen::Index(3 * n), cols = Eigen::Index(active.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(rows, cols);
  Eigen::VectorXd b(rows);
  std::vector<double> scale(n);
  for (std::size_t i = 0; i < n; ++i) {
    scale[i] = 1.0 / (p[i].mass_kg * kG);  // balance in units of the tomato's weight
    b.segment<3>(Eigen::Index(3 * i)) = -tangential(p[i], f[i]) * scale[i];
  }
  for (std::size_t k = 0; k < active.size(); ++k) {
    const auto& c = active[k];
    const std::size_t i = std::size_t(c.i);
    A.block<3, 1>(Eigen::Index(3 * i), Eigen::Index(k)) += tangential(p[i], c.n) * scale[i];
    if (c.j >= 0) {
      const std::size_t j = std::size_t(c.j);
      const double l = c.pedicel ? c.lever : 1.0;
      A.block<3, 1>(Eigen::Index(3 * j), Eigen::Index(k)) -= l * tangential(p[j], c.n) * scale[j];
    }
  }
  const Eigen::VectorXd lambda = cols > 0 ? nnls(A, b) : Eigen::VectorXd();
  const Eigen::VectorXd r = (cols > 0 ? Eigen::VectorXd(A * lambda) : Eigen::VectorXd::Zero(rows)) - b;
  rep.max_torque_residual = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    rep.max_torque_residual = std::max(rep.max_torque_residual, r.segment<3>(Eigen::Index(3 * i)).norm());

  contacts.clear();
  contact_force.assign(n, Eigen::Vector3d::Zero());
  rep.max_penetration_m = 0.0;
  for (std::size_t k = 0; k < active.size(); ++k) {
    const auto& c = active[k];
    rep.max_penetration_m = std::max(rep.max_penetration_m, -c.gap);
    if (!(lambda[Eigen::Index(k)] > 1e-6)) continue;
    const Eigen::Vector3d F = lambda[Eigen::Index(k)] * c.n;
    contact_force[std::size_t(c.i)] += F;
    if (c.j >= 0 && !c.pedicel) contact_force[std::size_t(c.j)] -= F;
    contacts.push_back({c.i, c.j,
                        c.pedicel ? ContactKind::kPedicel : (c.j < 0 ? ContactKind::kPeduncle : ContactKind::kFruit),
                        lambda[Eigen::Index(k)]});
  }
}

// The rest state by gradient projection: each iteration takes a step along
// the free (gravity + spring) forces and projects it onto the set of moves
// that keep every contact closed or opening (linearised, within 1 cm): the
// nearest such move, from the small QP's dual solved by projected
// Gauss-Seidel. At the fixed point the multipliers over the step are the
// contact forces (KKT), checked independently by balance_contacts.
RelaxationReport relax(std::vector<Pendulum>& p, const std::vector<Segment>& peduncle, double pedicel_radius,
                       std::vector<TrussContact>& contacts, std::vector<Eigen::Vector3d>& contact_force) {
  RelaxationReport rep;
  // Step [m/N] stable for the stiffest pendulum (gravity + spring restoring rate).
  double k_max = 0.0;
  for (const auto& q : p) k_max = std::max(k_max, (q.mass_kg * kG + q.stiffness / q.arm()) / q.arm());
  const double step = 0.6 / k_max;
  const int kMaxIter = 20000;
  for (int it = 0; it < kMaxIter; ++it) {
    ++rep.iterations;
    if (relax_step(p, peduncle, pedicel_radius, step) < 1e-10) break;
  }
  balance_contacts(p, peduncle, pedicel_radius, contacts, contact_force, rep);
  rep.converged = rep.iterations < kMaxIter && rep.max_torque_residual < 1e-3 && rep.max_penetration_m < 1e-4;
  return rep;
}

int tomato_count(TrussClass c, Rng& rng) {
  switch (c) {
    case TrussClass::kA: return rng.integer(1, 2);
    case TrussClass::kB: return rng.integer(3, 4);
    case TrussClass::kC: return rng.integer(5, 8);
  }
  return 1;
}

// A leaflet: an ellipse-like fan of triangles with a raised midrib, in the
// object frame's x-y plane (x along the leaf), both faces visible.
MeshShape leaflet(double length, double width, double fold) {
  MeshShape m;
  const int k = 14;
  m.vertices.emplace_back(0, 0, fold);  // centre, raised
  for (int i = 0; i < k; ++i) {
    const double a = 2.0 * M_PI * i / k;
    // Pointed tip: narrower towards +x.
    const double w = 0.5 * width * std::sin(a) * (1.0 - 0.35 * std::max(0.0, std::cos(a)));
    m.vertices.emplace_back(0.5 * length * std::cos(a), w, 0.0);
  }
  for (int i = 0; i < k; ++i) m.triangles.emplace_back(0, 1 + i, 1 + (i + 1) % k);
  return m;
}

Eigen::Isometry3d pose_from(const Eigen::Vector3d& t, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

// The fruit's surface in its own frame (z towards the calyx): an oblate
// spheroid (equatorial a, polar c) with `lobes` shallow ribs, 24 x 16 facets
// (sagitta under 1% of the radius), cut into 8 x 4 patches that become
// separate objects: a ray then tests only the patches whose bounding spheres
// it passes (a few dozen facets) instead of all 720.
std::vector<MeshShape> fruit_patches(const TrussTomato& t) {
  constexpr int kRings = 16, kSegs = 24, kPatchRings = 4, kPatchSegs = 3;
  auto vertex = [&](int r, int k) {
    const double theta = M_PI * r / kRings, phi = 2.0 * M_PI * k / kSegs;
    const double rr = 1.0 + t.rib_amplitude * std::pow(std::sin(theta), 2) * std::cos(t.lobes * phi + t.rib_phase_rad);
    return Eigen::Vector3d(t.equatorial_radius_m * rr * std::sin(theta) * std::cos(phi),
                           t.equatorial_radius_m * rr * std::sin(theta) * std::sin(phi),
                           t.polar_radius_m * std::cos(theta));
  };
  std::vector<MeshShape> patches;
  for (int r0 = 0; r0 < kRings; r0 += kPatchRings) {
    for (int k0 = 0; k0 < kSegs; k0 += kPatchSegs) {
      MeshShape m;
      auto add = [&](const Eigen::Vector3d& v) {
        m.vertices.push_back(v);
        return static_cast<int>(m.vertices.size()) - 1;
      };
      for (int r = r0; r < r0 + kPatchRings; ++r) {
        for (int k = k0; k < k0 + kPatchSegs; ++k) {
          const Eigen::Vector3d a = vertex(r, k), b = vertex(r + 1, k), c = vertex(r + 1, k + 1), d = vertex(r, k + 1);
          if (r > 0) m.triangles.emplace_back(add(a), add(c), add(d));           // not at the calyx pole
          if (r + 1 < kRings) m.triangles.emplace_back(add(a), add(b), add(c));  // not at the blossom pole
        }
      }
      patches.push_back(std::move(m));
    }
  }
  return patches;
}

Eigen::Matrix3d random_rotation(Rng& rng) {
  Eigen::Quaterniond q(rng.normal(), rng.normal(), rng.normal(), rng.normal());
  q.normalize();
  return q.toRotationMatrix();
}

Object rod(std::string name, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double radius, MaterialId m) {
  Object o;
  o.name = std::move(name);
  o.shape = RodShape{a, b, radius};
  o.material = m;
  return o;
}

// A bent rod: a tube of 8 facets around a polyline (one object, so that it
// goes when its fruit is picked, as a straight pedicel's rod does).
MeshShape tube(const std::vector<Eigen::Vector3d>& path, double radius) {
  constexpr int kSides = 8;
  MeshShape m;
  for (std::size_t k = 0; k < path.size(); ++k) {
    const Eigen::Vector3d t = (path[std::min(k + 1, path.size() - 1)] - path[k == 0 ? 0 : k - 1]).normalized();
    const Eigen::Vector3d a = t.unitOrthogonal(), b = t.cross(a);
    for (int j = 0; j < kSides; ++j) {
      const double phi = 2.0 * M_PI * j / kSides;
      m.vertices.push_back(path[k] + radius * (std::cos(phi) * a + std::sin(phi) * b));
    }
  }
  for (int k = 0; k + 1 < int(path.size()); ++k) {
    for (int j = 0; j < kSides; ++j) {
      const int a = k * kSides + j, b = k * kSides + (j + 1) % kSides;
      m.triangles.emplace_back(a, b, b + kSides);
      m.triangles.emplace_back(a, b + kSides, a + kSides);
    }
  }
  return m;
}

struct Layout {
  std::vector<Pendulum> pendulums;
  std::vector<Segment> peduncle;
  std::vector<Eigen::Vector3d> polyline;
};

// Peduncle and pendulums before settling.
Layout draw_layout(const TrussParams& P, int n, Rng& rng) {
  Layout L;
  // Anchor spacing along the peduncle and depth scatter by class.
  double spacing_lo = 0.07, spacing_hi = 0.10, depth_scatter = 0.0;
  switch (P.complexity) {
    case TrussClass::kA: break;
    case TrussClass::kB:
      spacing_lo = 0.035;
      spacing_hi = 0.055;
      depth_scatter = 0.012;
      break;
    case TrussClass::kC:
      spacing_lo = 0.018;
      spacing_hi = 0.032;
      depth_scatter = 0.03;
      break;
  }
  // The peduncle leaves the main stem sideways and arches down.
  const double side = rng.chance(0.5) ? 1.0 : -1.0;
  const double lead = 0.04;
  std::vector<double> spacing(static_cast<std::size_t>(n));
  double length = lead;
  for (auto& s : spacing) {
    s = rng.uniform(spacing_lo, spacing_hi);
    length += s;
  }
  const double droop = rng.uniform(0.2, 0.9);           // how fast it bends down [rad over its length]
  const double start_angle = rng.uniform(-0.15, 0.35);  // initial angle below horizontal
  const double yaw = rng.uniform(-0.35, 0.35);          // swing towards or away from the camera
  const int segs = std::max(4, static_cast<int>(length / 0.015));
  Eigen::Vector3d pt = P.origin_m;
  L.polyline.push_back(pt);
  std::vector<double> arc{0.0};
  for (int k = 0; k < segs; ++k) {
    const double s = (k + 0.5) / segs;
    const double pitch = start_angle + droop * s;
    const double turn = yaw + P.peduncle_curl_deg * M_PI / 180.0 * s;
    const Eigen::Vector3d dir(side * std::cos(pitch) * std::cos(turn), std::cos(pitch) * std::sin(turn),
                              -std::sin(pitch));
    pt += (length / segs) * dir;
    L.polyline.push_back(pt);
    arc.push_back(arc.back() + length / segs);
  }
  for (std::size_t k = 0; k + 1 < L.polyline.size(); ++k)
    L.peduncle.push_back({L.polyline[k], L.polyline[k + 1], P.peduncle_radius_m});
  auto at_arc = [&](double s) {
    for (std::size_t k = 0; k + 1 < arc.size(); ++k) {
      if (s <= arc[k + 1]) {
        const double t = (s - arc[k]) / (arc[k + 1] - arc[k]);
        return Eigen::Vector3d(L.polyline[k] + t * (L.polyline[k + 1] - L.polyline[k]));
      }
    }
    return L.polyline.back();
  };
  double s = lead;
  for (int i = 0; i < n; ++i) {
    s += spacing[static_cast<std::size_t>(i)] * (i == 0 ? 0.5 : 1.0);
    Pendulum p;
    // A short spur off the peduncle, alternating sides and in depth.
    const Eigen::Vector3d on = at_arc(std::min(s, length));
    const double spur_side = (i % 2 == 0 ? 1.0 : -1.0);
    p.anchor = on + Eigen::Vector3d(0, spur_side * rng.uniform(0.0, 0.006) + depth_scatter * rng.uniform(-1, 1),
                                    -P.peduncle_radius_m - 0.001);
    // An oblate, slightly ribbed fruit of volume-equivalent radius r_eq.
    p.r_eq = rng.uniform(P.radius_min_m, P.radius_max_m);
    const double flat = rng.uniform(P.flatness_min, P.flatness_max);
    p.equatorial = p.r_eq / std::cbrt(flat);
    p.polar_m = flat * p.equatorial;
    p.rib = rng.uniform(0.0, P.rib_max);
    p.lobes = rng.integer(5, 6);
    p.rib_phase = rng.uniform(0.0, 2.0 * M_PI);
    if (!P.mesh_fruit) p.equatorial = p.polar_m = p.r_eq, p.rib = 0.0;
    p.radius_m = std::max(p.equatorial * (1.0 + p.rib), p.polar_m);
    p.pedicel_m = rng.uniform(P.pedicel_length_min_m, P.pedicel_length_max_m);
    p.mass_kg = P.density_kg_m3 * 4.0 / 3.0 * M_PI * std::pow(p.r_eq, 3);
    p.stiffness = rng.uniform(P.stiffness_ratio_min, P.stiffness_ratio_max) * p.mass_kg * kG * p.arm();
    const double tilt = rng.uniform(0.0, P.rest_tilt_max_deg * M_PI / 180.0);
    // In depth-scattered classes some fruit hang towards or away from the camera.
    double az = rng.uniform(-M_PI, M_PI);
    p.rest = down_tilted(tilt, az);
    p.d = p.rest;
    L.pendulums.push_back(p);
  }
  return L;
}

// ---- kElasticRod: the same layout as a network of elastic rods ----

struct RodTruss {
  rod::Network net;
  std::vector<int> fruit_node;                  // per tomato: its centre
  std::vector<std::vector<int>> pedicel_nodes;  // per tomato: anchor .. calyx
  std::vector<int> peduncle_nodes;
};

// Axial stiffness capped at 10 E I / l^2 (stretch stays under 0.5 % under
// the truss's loads) so that bending, not stretching, sets how stiff the
// settle's equations are.
double axial(double E, double r, double l) {
  return std::min(E * M_PI * r * r, 10.0 * E * rod::round_section_inertia(r) / (l * l));
}

void lump_rod_mass(rod::Network& net, int a, int b, double radius, double density) {
  const double m = density * M_PI * radius * radius * (net.x[std::size_t(b)] - net.x[std::size_t(a)]).norm();
  net.lumped_mass_kg[std::size_t(a)] += 0.5 * m;
  net.lumped_mass_kg[std::size_t(b)] += 0.5 * m;
}

// The peduncle as a rod clamped at the main stem (a fixed ghost node before
// its root holds the root's direction), its rest shape the drawn arch at
// half the drawn resolution.
void add_peduncle(const TrussParams& P, const Layout& L, double E, RodTruss& R) {
  rod::Network& net = R.net;
  std::vector<Eigen::Vector3d> poly;
  for (std::size_t k = 0; k < L.polyline.size(); k += 2) poly.push_back(L.polyline[k]);
  if ((L.polyline.size() - 1) % 2 != 0) poly.push_back(L.polyline.back());
  const double r = P.peduncle_radius_m, EI = E * rod::round_section_inertia(r);
  const int ghost = net.add_node(poly[0] - (poly[1] - poly[0]), true);
  for (std::size_t k = 0; k < poly.size(); ++k) R.peduncle_nodes.push_back(net.add_node(poly[k], k == 0));
  const auto& q = R.peduncle_nodes;
  for (std::size_t k = 0; k + 1 < q.size(); ++k) {
    const double l = (poly[k + 1] - poly[k]).norm();
    net.add_segment(q[k], q[k + 1], axial(E, r, l));
    net.tubes.push_back({q[k], q[k + 1], -1, r});
    lump_rod_mass(net, q[k], q[k + 1], r, P.density_kg_m3);
    // The clamp's hinge stands for half an element: twice the stiffness.
    net.add_hinge(k == 0 ? ghost : q[k - 1], q[k], q[k], q[k + 1], (k == 0 ? 2.0 : 1.0) * EI / l);
  }
}

// Pedicel i as a straight rod along its rest direction, tied to the
// peduncle at its anchor and bent against the peduncle's direction there;
// its fruit a node welded to the calyx (10 times a pedicel element's
// stiffness), with the fruit's mass and bounding radius.
void add_pedicel(const TrussParams& P, const Pendulum& p, int i, double E, RodTruss& R) {
  rod::Network& net = R.net;
  const auto& q = R.peduncle_nodes;
  std::size_t seg = 0;
  double best = 1e9, w = 0.0;
  for (std::size_t k = 0; k + 1 < q.size(); ++k) {
    const Eigen::Vector3d a = net.x[std::size_t(q[k])], b = net.x[std::size_t(q[k + 1])];
    const double t = closest_t(p.anchor, a, b), d = (p.anchor - (a + t * (b - a))).norm();
    if (d < best) best = d, seg = k, w = t;
  }
  const int K = P.pedicel_segments;
  const double r = P.pedicel_radius_m, l = p.pedicel_m / K, EI = E * rod::round_section_inertia(r);
  const double ax = axial(E, r, l);
  std::vector<int> nodes;
  for (int k = 0; k <= K; ++k) nodes.push_back(net.add_node(p.anchor + (k * l) * p.rest));
  const Eigen::Vector3d on = (1 - w) * net.x[std::size_t(q[seg])] + w * net.x[std::size_t(q[seg + 1])];
  net.ties.push_back({nodes[0], q[seg], q[seg + 1], w, p.anchor - on, 10.0 * ax / l});
  net.add_hinge(q[seg], q[seg + 1], nodes[0], nodes[1], 2.0 * EI / l);  // the knuckle: half an element
  for (int k = 0; k < K; ++k) {
    net.add_segment(nodes[std::size_t(k)], nodes[std::size_t(k + 1)], ax);
    net.tubes.push_back({nodes[std::size_t(k)], nodes[std::size_t(k + 1)], i, r});
    lump_rod_mass(net, nodes[std::size_t(k)], nodes[std::size_t(k + 1)], r, P.density_kg_m3);
    if (k > 0)
      net.add_hinge(nodes[std::size_t(k - 1)], nodes[std::size_t(k)], nodes[std::size_t(k)], nodes[std::size_t(k + 1)],
                    EI / l);
  }
  const int calyx = nodes.back(), centre = net.add_node(p.anchor + p.arm() * p.rest);
  net.add_segment(calyx, centre, 10.0 * ax * p.polar_m / l);
  net.add_hinge(nodes[std::size_t(K - 1)], calyx, calyx, centre, 10.0 * EI / l);
  net.bodies.push_back({centre, i, p.radius_m, p.mass_kg});
  R.fruit_node.push_back(centre);
  R.pedicel_nodes.push_back(std::move(nodes));
}

// Moduli from their own stream, so that the layout's draws are the
// pendulum world's.
RodTruss build_rod_truss(const TrussParams& P, const Layout& L, Rng& moduli) {
  RodTruss R;
  add_peduncle(P, L, moduli.uniform(P.peduncle_young_min_pa, P.peduncle_young_max_pa), R);
  for (std::size_t i = 0; i < L.pendulums.size(); ++i)
    add_pedicel(P, L.pendulums[i], int(i), moduli.uniform(P.pedicel_young_min_pa, P.pedicel_young_max_pa), R);
  return R;
}

// The settled rods back into the layout (pendulum directions anchor ->
// centre, for the camera and the class checks) and the truth's contacts and
// forces; a rest state with penetrations over 0.5 mm does not count as settled.
RelaxationReport settle_rods(const TrussParams& P, Layout& L, Rng& moduli, RodTruss& R,
                             std::vector<TrussContact>& contacts, std::vector<Eigen::Vector3d>& contact_force) {
  R = build_rod_truss(P, L, moduli);
  rod::SettleOptions o;
  o.friction = P.friction;
  const rod::SettleReport s = rod::settle(R.net, o);
  RelaxationReport rep;
  double lightest = 1e9;
  for (const auto& p : L.pendulums) lightest = std::min(lightest, p.mass_kg * kG);
  rep.iterations = s.iterations;
  rep.max_torque_residual = s.max_residual_n / lightest;
  rep.max_penetration_m = s.max_penetration_m;
  rep.converged = s.converged && s.max_penetration_m < 5e-4;
  contacts.clear();
  contact_force.assign(L.pendulums.size(), Eigen::Vector3d::Zero());
  for (const auto& c : s.contacts) {
    contact_force[std::size_t(c.body)] += c.force_on_body;
    if (c.with == rod::ContactWith::kBody) {
      contact_force[std::size_t(c.other)] -= c.force_on_body;
      contacts.push_back({c.body, c.other, ContactKind::kFruit, c.normal_n});
    } else {
      contacts.push_back({c.body, c.other, c.other < 0 ? ContactKind::kPeduncle : ContactKind::kPedicel, c.normal_n});
    }
  }
  for (std::size_t i = 0; i < L.pendulums.size(); ++i) {
    Pendulum& p = L.pendulums[i];
    p.anchor = R.net.x[std::size_t(R.pedicel_nodes[i].front())];
    p.rod_centre = R.net.x[std::size_t(R.fruit_node[i])];
    p.d = (*p.rod_centre - p.anchor).normalized();
  }
  L.polyline.clear();
  for (int k : R.peduncle_nodes) L.polyline.push_back(R.net.x[std::size_t(k)]);
  return rep;
}

// Tomato i and its truth at rest (R: the settled rods, kElasticRod only).
TrussTomato tomato_at_rest(const TrussParams& params, const Pendulum& p, std::size_t i, const RodTruss& R,
                           const Eigen::Vector3d& contact_force) {
  TrussTomato t;
  t.centre_m = p.centre();
  t.radius_m = p.r_eq;
  t.equatorial_radius_m = p.equatorial;
  t.polar_radius_m = p.polar_m;
  t.rib_amplitude = p.rib;
  t.lobes = p.lobes;
  t.rib_phase_rad = p.rib_phase;
  t.bounding_radius_m = p.radius_m;
  t.mass_kg = p.mass_kg;
  t.anchor_m = p.anchor;
  t.calyx_m = p.calyx();
  t.pedicel_dir = -p.d;
  t.pedicel_path_m = {t.anchor_m, t.calyx_m};
  if (params.physics == TrussPhysics::kElasticRod) {
    // The fruit's axis is the pedicel's tangent at the calyx.
    t.pedicel_path_m.clear();
    for (int k : R.pedicel_nodes[i]) t.pedicel_path_m.push_back(R.net.x[std::size_t(k)]);
    t.calyx_m = t.pedicel_path_m.back();
    t.pedicel_dir = (t.calyx_m - t.centre_m).normalized();
  }
  // Eq. 4.22: the pedicel balances gravity and the contacts on the fruit.
  t.pedicel_force_n = -(Eigen::Vector3d(0, 0, -p.mass_kg * kG) + contact_force);
  t.object_name = params.name + "_tomato_" + std::to_string(i);
  return t;
}

}  // namespace

std::optional<TrussClass> parse_truss_class(std::string_view s) {
  if (s == "A" || s == "a") return TrussClass::kA;
  if (s == "B" || s == "b") return TrussClass::kB;
  if (s == "C" || s == "c") return TrussClass::kC;
  return std::nullopt;
}

std::optional<TrussPhysics> parse_truss_physics(std::string_view s) {
  if (s == "pendulum") return TrussPhysics::kPendulum;
  if (s == "elastic_rod") return TrussPhysics::kElasticRod;
  return std::nullopt;
}

common::Status set_truss_option(TrussParams& p, std::string_view key, std::string_view value) {
  const std::string v(value);
  if (key == "physics") {
    const auto ph = parse_truss_physics(v);
    if (!ph) return common::Status::invalid("physics must be pendulum or elastic_rod, got '" + v + "'");
    p.physics = *ph;
    return p.validate();
  }
  double x = 0.0;
  std::size_t used = 0;
  try {
    x = std::stod(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != v.size() || !std::isfinite(x))
    return common::Status::invalid("truss option '" + std::string(key) + "' wants a number, got '" + v + "'");
  auto integer = [&](int& field) {
    if (x != std::floor(x))
      return common::Status::invalid("truss option '" + std::string(key) + "' wants a whole number");
    field = static_cast<int>(x);
    return p.validate();
  };
  const std::pair<const char*, double*> reals[] = {{"pedicel_young_min_pa", &p.pedicel_young_min_pa},
                                                   {"pedicel_young_max_pa", &p.pedicel_young_max_pa},
                                                   {"peduncle_young_min_pa", &p.peduncle_young_min_pa},
                                                   {"peduncle_young_max_pa", &p.peduncle_young_max_pa},
                                                   {"friction", &p.friction},
                                                   {"stem_bend_deg", &p.stem_bend_deg},
                                                   {"peduncle_curl_deg", &p.peduncle_curl_deg},
                                                   {"front_leaf_offset_min", &p.front_leaf_offset_min},
                                                   {"front_leaf_offset_max", &p.front_leaf_offset_max},
                                                   {"rest_tilt_max_deg", &p.rest_tilt_max_deg}};
  for (const auto& [name, field] : reals) {
    if (key != name) continue;
    *field = x;
    return p.validate();
  }
  if (key == "pedicel_segments") return integer(p.pedicel_segments);
  if (key == "pedicel_leaves") return integer(p.pedicel_leaves);
  if (key == "front_leaves") return integer(p.front_leaves);
  return common::Status::invalid(
      "unknown truss option '" + std::string(key) +
      "' (physics, pedicel_young_min_pa, pedicel_young_max_pa, peduncle_young_min_pa, "
      "peduncle_young_max_pa, friction, pedicel_segments, stem_bend_deg, peduncle_curl_deg, "
      "pedicel_leaves, front_leaves, front_leaf_offset_min, front_leaf_offset_max, rest_tilt_max_deg)");
}

common::Status TrussParams::validate() const {
  if (num_tomatoes < 0 || num_tomatoes > 8) return common::Status::invalid("num_tomatoes must be 0 (by class) or 1..8");
  if (!(radius_min_m > 0.005) || !(radius_max_m >= radius_min_m) || radius_max_m > 0.08)
    return common::Status::invalid("tomato radii must satisfy 0.005 < radius_min_m <= radius_max_m <= 0.08 m");
  if (!(pedicel_length_min_m > 0.005) || !(pedicel_length_max_m >= pedicel_length_min_m) || pedicel_length_max_m > 0.15)
    return common::Status::invalid("pedicel lengths must satisfy 0.005 < min <= max <= 0.15 m");
  if (!(pedicel_radius_m > 0) || !(peduncle_radius_m > 0))
    return common::Status::invalid("pedicel and peduncle radii must be > 0");
  if (!(flatness_min >= 0.5) || !(flatness_max >= flatness_min) || !(flatness_max <= 1.2))
    return common::Status::invalid("flatness must satisfy 0.5 <= flatness_min <= flatness_max <= 1.2");
  if (!(rib_max >= 0 && rib_max <= 0.1)) return common::Status::invalid("rib_max must be in [0, 0.1]");
  if (!(density_kg_m3 > 0)) return common::Status::invalid("density_kg_m3 must be > 0");
  if (!(stiffness_ratio_min >= 0) || !(stiffness_ratio_max >= stiffness_ratio_min))
    return common::Status::invalid("stiffness ratios must be 0 <= min <= max");
  if (!(rest_tilt_max_deg >= 0 && rest_tilt_max_deg <= 80))
    return common::Status::invalid("rest_tilt_max_deg must be in [0, 80]");
  if (front_leaves < -1 || front_leaves > 8)
    return common::Status::invalid("front_leaves must be -1 (by class) or 0..8");
  if (!(camera_distance_m >= 0.2 && camera_distance_m <= 2.0))
    return common::Status::invalid("camera_distance_m must be in [0.2, 2] m");
  if (!(camera_jitter_m >= 0) || !(camera_yaw_jitter_deg >= 0))
    return common::Status::invalid("camera jitters must be >= 0");
  if (!origin_m.allFinite()) return common::Status::invalid("origin_m must be finite");
  if (!(pedicel_young_min_pa > 0) || !(pedicel_young_max_pa >= pedicel_young_min_pa) || !(peduncle_young_min_pa > 0) ||
      !(peduncle_young_max_pa >= peduncle_young_min_pa) || pedicel_young_max_pa > 1e12 || peduncle_young_max_pa > 1e12)
    return common::Status::invalid("Young's moduli must satisfy 0 < min <= max <= 1e12 Pa");
  if (!(friction >= 0 && friction <= 2)) return common::Status::invalid("friction must be in [0, 2]");
  if (pedicel_segments < 2 || pedicel_segments > 16)
    return common::Status::invalid("pedicel_segments must be in 2..16");
  if (!(std::abs(stem_bend_deg) <= 120)) return common::Status::invalid("stem_bend_deg must be in [-120, 120]");
  if (!(std::abs(peduncle_curl_deg) <= 180)) return common::Status::invalid("peduncle_curl_deg must be in [-180, 180]");
  if (pedicel_leaves < 0 || pedicel_leaves > 8) return common::Status::invalid("pedicel_leaves must be in 0..8");
  if (!(front_leaf_offset_min >= 0) || !(front_leaf_offset_max >= front_leaf_offset_min) ||
      !(front_leaf_offset_max <= 5))
    return common::Status::invalid("front leaf offsets must satisfy 0 <= min <= max <= 5 radii");
  return common::Status{};
}

Truss make_truss(const TrussParams& params) {
  if (const common::Status why = params.validate(); !why.ok()) throw std::invalid_argument("truss: " + why.message);
  Truss T;
  T.params = params;
  Rng rng(params.seed);
  const int n = params.num_tomatoes > 0 ? params.num_tomatoes : tomato_count(params.complexity, rng);

  Layout L;
  RodTruss R;
  Rng moduli(params.seed ^ 0x3c6ef372fe94f82bULL);
  std::vector<TrussContact> contacts;
  std::vector<Eigen::Vector3d> contact_force;
  for (int attempt = 0;; ++attempt) {
    L = draw_layout(params, n, rng);
    if (params.physics == TrussPhysics::kElasticRod)
      T.relaxation = settle_rods(params, L, moduli, R, contacts, contact_force);
    else
      T.relaxation = relax(L.pendulums, L.peduncle, params.pedicel_radius_m, contacts, contact_force);
    T.relaxation.restarts = attempt;
    bool ok = T.relaxation.converged;
    // Fruit must clear the floor.
    for (const auto& p : L.pendulums) ok = ok && p.centre().z() > p.radius_m + 0.05;

    // Camera in front (-y side), looking at the fruit.
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : L.pendulums) mean += p.centre();
    mean /= static_cast<double>(L.pendulums.size());
    const double yaw = rng.uniform(-1, 1) * params.camera_yaw_jitter_deg * M_PI / 180.0;
    const Eigen::Vector3d offset(params.camera_jitter_m * rng.uniform(-1, 1), -params.camera_distance_m,
                                 params.camera_jitter_m * rng.uniform(-1, 1) + 0.05);
    const Eigen::Vector3d eye = mean + Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * offset;
    T.T_world_camera = look_at(eye, mean);

    // Class A: simple, no contacts and no fruit hiding another (Figure 4.8 A).
    if (ok && params.complexity == TrussClass::kA) {
      ok = contacts.empty();  // no fruit, peduncle or pedicel contacts
      const Eigen::Isometry3d T_cam_world = T.T_world_camera.inverse();
      for (std::size_t i = 0; ok && i < L.pendulums.size(); ++i) {
        for (std::size_t j = i + 1; ok && j < L.pendulums.size(); ++j) {
          const Eigen::Vector3d a = T_cam_world * L.pendulums[i].centre(), b = T_cam_world * L.pendulums[j].centre();
          // Angular separation against the sum of angular radii.
          const double sep = std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
          ok = sep >
               std::asin(L.pendulums[i].radius_m / a.norm()) + std::asin(L.pendulums[j].radius_m / b.norm()) + 0.01;
        }
      }
    }
    if (ok || attempt >= 40) break;
  }

  for (std::size_t i = 0; i < L.pendulums.size(); ++i)
    T.tomatoes.push_back(tomato_at_rest(params, L.pendulums[i], i, R, contact_force[i]));
  T.contacts = contacts;
  T.peduncle_m = L.polyline;

  // Materials: each tomato its own shade of ripe red.
  MaterialLibrary builtin = MaterialLibrary::builtin();
  const Material base = builtin.get(*builtin.find("tomato_red"));
  for (std::size_t i = 0; i < T.tomatoes.size(); ++i) {
    Material m = base;
    m.name = "tomato_red_" + params.name + "_" + std::to_string(i);
    m.rgb = {rng.uniform(0.55, 0.80), rng.uniform(0.035, 0.10), rng.uniform(0.02, 0.06)};
    T.materials.push_back(m);
  }
  return T;
}

namespace {

MaterialId need(World& w, const std::string& name) {
  const auto id = w.materials().find(name);
  if (!id) throw std::invalid_argument("truss: material '" + name + "' missing from the world's library");
  return *id;
}

// Adds a truss's tomatoes, pedicels, calyxes and peduncle.
void add_fruit(const Truss& T, World& world) {
  for (const auto& m : T.materials) world.materials().add(m);
  const MaterialId stem = need(world, "stem");
  const std::string& nm = T.params.name;
  for (std::size_t i = 0; i < T.tomatoes.size(); ++i) {
    const TrussTomato& t = T.tomatoes[i];
    const Eigen::Matrix3d up_to_axis =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), t.pedicel_dir).toRotationMatrix();
    const MaterialId skin = need(world, T.materials[i].name);
    if (T.params.mesh_fruit) {
      int k = 0;
      for (auto& patch : fruit_patches(t)) {
        Object s;
        s.name = t.object_name + "_p" + std::to_string(k++);
        s.shape = std::move(patch);
        s.T_world_object = pose_from(t.centre_m, up_to_axis);
        s.material = skin;
        world.add(std::move(s));
      }
    } else {
      Object s;
      s.name = t.object_name;
      s.shape = SphereShape{t.radius_m};
      s.T_world_object = pose_from(t.centre_m, Eigen::Matrix3d::Identity());
      s.material = skin;
      world.add(std::move(s));
    }
    if (t.pedicel_path_m.size() > 2) {
      Object o;
      o.name = nm + "_pedicel_" + std::to_string(i);
      o.shape = tube(t.pedicel_path_m, T.params.pedicel_radius_m);
      o.material = stem;
      world.add(std::move(o));
    } else {
      world.add(rod(nm + "_pedicel_" + std::to_string(i), t.anchor_m, t.calyx_m, T.params.pedicel_radius_m, stem));
    }
    // Sepals: a thin green disc on the fruit's top, around the calyx.
    Object c;
    c.name = nm + "_calyx_" + std::to_string(i);
    c.shape = CylinderShape{0.45 * t.radius_m, 0.002};
    c.T_world_object = pose_from(t.centre_m + (t.polar_radius_m - 0.002) * t.pedicel_dir, up_to_axis);
    c.material = stem;
    world.add(std::move(c));
  }
  for (std::size_t k = 0; k + 1 < T.peduncle_m.size(); ++k)
    world.add(rod(nm + "_peduncle_" + std::to_string(k), T.peduncle_m[k], T.peduncle_m[k + 1],
                  T.params.peduncle_radius_m, stem));
}

// Leaves in front: each hides part of one tomato from the camera.
void add_front_leaves(const Truss& T, World& world, Rng& rng, MaterialId leaf) {
  const TrussParams& P = T.params;
  const Eigen::Vector3d eye = T.T_world_camera.translation();
  int front = P.front_leaves;
  if (front < 0) {
    switch (P.complexity) {
      case TrussClass::kA: front = 0; break;
      case TrussClass::kB: front = rng.integer(1, 2); break;
      case TrussClass::kC: front = rng.integer(2, 4); break;
    }
  }
  for (int k = 0; k < front; ++k) {
    const TrussTomato& t =
        T.tomatoes[static_cast<std::size_t>(rng.integer(0, static_cast<int>(T.tomatoes.size()) - 1))];
    const Eigen::Vector3d to_t = t.centre_m - eye;
    // Between the camera and the fruit, well clear of the fruit.
    const double back = rng.uniform(t.radius_m + 0.04, t.radius_m + 0.12);
    Eigen::Vector3d at = t.centre_m - back * to_t.normalized();
    // Offset sideways so that the leaf covers an edge of the fruit only.
    const Eigen::Vector3d side = to_t.cross(Eigen::Vector3d::UnitZ()).normalized();
    const double a = rng.uniform(-M_PI, M_PI);
    const double off =
        t.radius_m * rng.uniform(P.front_leaf_offset_min, P.front_leaf_offset_max) * (1.0 - back / to_t.norm());
    at += off * (std::cos(a) * side + std::sin(a) * Eigen::Vector3d::UnitZ());
    Object o;
    o.name = P.name + "_leaf_front_" + std::to_string(k);
    o.shape = leaflet(rng.uniform(0.05, 0.09), rng.uniform(0.025, 0.045), rng.uniform(0.002, 0.008));
    // Roughly facing the camera, tilted at random.
    const Eigen::Matrix3d face =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), -to_t.normalized()).toRotationMatrix();
    const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(rng.uniform(-M_PI, M_PI), Eigen::Vector3d::UnitZ()) *
                                  Eigen::AngleAxisd(rng.uniform(-0.6, 0.6), Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    o.T_world_object = pose_from(at, face * tilt);
    o.material = leaf;
    world.add(std::move(o));
  }
}

// Leaves between the camera and pedicels: each hides the middle of one
// pedicel (what the laser verification and the cut look for), from its own
// random stream so that the other leaves stay where they were.
void add_pedicel_leaves(const Truss& T, World& world, MaterialId leaf) {
  const TrussParams& P = T.params;
  Rng rng(P.seed ^ 0x1eaf5eedULL);
  const Eigen::Vector3d eye = T.T_world_camera.translation();
  for (int k = 0; k < P.pedicel_leaves; ++k) {
    const TrussTomato& t = T.tomatoes[static_cast<std::size_t>(k) % T.tomatoes.size()];
    const Eigen::Vector3d mid = 0.5 * (t.anchor_m + t.calyx_m), to = mid - eye;
    const Eigen::Vector3d at = mid - rng.uniform(0.05, 0.12) * to.normalized() +
                               rng.uniform(-0.01, 0.01) * to.cross(Eigen::Vector3d::UnitZ()).normalized();
    Object o;
    o.name = P.name + "_leaf_pedicel_" + std::to_string(k);
    o.shape = leaflet(rng.uniform(0.04, 0.07), rng.uniform(0.02, 0.035), rng.uniform(0.002, 0.006));
    const Eigen::Matrix3d face =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), -to.normalized()).toRotationMatrix();
    o.T_world_object =
        pose_from(at, face * Eigen::AngleAxisd(rng.uniform(-M_PI, M_PI), Eigen::Vector3d::UnitZ()).toRotationMatrix());
    o.material = leaf;
    world.add(std::move(o));
  }
}

// The main stem the peduncle leaves from, a little behind it: one straight
// rod, or a bow of 8 rods bending by stem_bend_deg in x about the origin.
void add_main_stem(const TrussParams& P, World& world, MaterialId stem) {
  const Eigen::Vector3d base = P.origin_m + Eigen::Vector3d(0, 0.02, 0);
  if (P.stem_bend_deg == 0.0) {
    world.add(rod(P.name + "_main_stem", base + Eigen::Vector3d(0, 0, -0.6), base + Eigen::Vector3d(0, 0, 0.35), 0.007,
                  stem));
    return;
  }
  constexpr int kPieces = 8;
  const double bend = P.stem_bend_deg * M_PI / 180.0, length = 0.95;
  auto at = [&](double s) {  // s from -0.6 to 0.35 along the stem; curvature bend / length
    const double phi = bend * s / length;
    return Eigen::Vector3d(base +
                           Eigen::Vector3d(length / bend * (1.0 - std::cos(phi)), 0, length / bend * std::sin(phi)));
  };
  for (int k = 0; k < kPieces; ++k) {
    const double s0 = -0.6 + length * k / kPieces, s1 = -0.6 + length * (k + 1) / kPieces;
    world.add(
        rod(P.name + "_main_stem" + (k == 0 ? std::string() : "_" + std::to_string(k)), at(s0), at(s1), 0.007, stem));
  }
}

// Leaves behind the truss, around the tomatoes' mean.
void add_background_leaves(const TrussParams& P, const Eigen::Vector3d& mean, World& world, Rng& rng, MaterialId leaf) {
  const int nb = rng.integer(3, 6);
  for (int k = 0; k < nb; ++k) {
    Object o;
    o.name = P.name + "_leaf_back_" + std::to_string(k);
    o.shape = leaflet(rng.uniform(0.06, 0.11), rng.uniform(0.03, 0.05), rng.uniform(0.002, 0.01));
    const Eigen::Vector3d at =
        mean + Eigen::Vector3d(rng.uniform(-0.2, 0.2), rng.uniform(0.12, 0.3), rng.uniform(-0.15, 0.2));
    o.T_world_object = pose_from(at, random_rotation(rng));
    o.material = leaf;
    world.add(std::move(o));
  }
}

// A second, smaller truss behind the first; returns its tomatoes.
std::vector<TrussTomato> add_distractor_truss(const TrussParams& P, World& world, Rng& rng) {
  TrussParams d;
  d.complexity = TrussClass::kB;
  d.num_tomatoes = rng.integer(2, 4);
  d.seed = P.seed * 7919 + 13;
  d.name = P.name + "_second";
  d.origin_m = P.origin_m + Eigen::Vector3d(rng.uniform(-0.2, 0.2), rng.uniform(0.22, 0.35), rng.uniform(-0.05, 0.05));
  d.front_leaves = 0;
  d.background_leaves = false;
  d.distractor_truss = false;
  d.room = false;
  d.physics = P.physics;  // the same world's physics and ranges
  d.pedicel_young_min_pa = P.pedicel_young_min_pa;
  d.pedicel_young_max_pa = P.pedicel_young_max_pa;
  d.peduncle_young_min_pa = P.peduncle_young_min_pa;
  d.peduncle_young_max_pa = P.peduncle_young_max_pa;
  d.friction = P.friction;
  d.pedicel_segments = P.pedicel_segments;
  d.peduncle_curl_deg = P.peduncle_curl_deg;
  d.rest_tilt_max_deg = P.rest_tilt_max_deg;
  const Truss other = make_truss(d);
  add_fruit(other, world);
  return other.tomatoes;
}

// A floor and a back wall behind the truss.
void add_room(const std::string& nm, const Eigen::Vector3d& mean, World& world) {
  Object f;
  f.name = nm + "_floor";
  f.shape = PlaneShape{Eigen::Vector2d(6, 6)};
  f.material = need(world, "grey_matte");
  world.add(std::move(f));
  Object w;
  w.name = nm + "_back_wall";
  w.shape = PlaneShape{Eigen::Vector2d(6, 4)};
  w.T_world_object = pose_from(
      Eigen::Vector3d(mean.x(), mean.y() + 1.2, 1.5),
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitY()).toRotationMatrix());
  w.material = need(world, "wall_paint");
  world.add(std::move(w));
}

}  // namespace

std::vector<TrussTomato> add_to_world(const Truss& T, World& world) {
  add_fruit(T, world);
  const TrussParams& P = T.params;
  Rng rng(P.seed ^ 0x5eed1eafULL);
  const MaterialId leaf = need(world, "leaf");
  const MaterialId stem = need(world, "stem");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& t : T.tomatoes) mean += t.centre_m;
  mean /= static_cast<double>(T.tomatoes.size());

  add_main_stem(P, world, stem);
  add_front_leaves(T, world, rng, leaf);
  if (P.background_leaves) add_background_leaves(P, mean, world, rng, leaf);
  std::vector<TrussTomato> second;
  if (P.distractor_truss && P.complexity != TrussClass::kA && rng.chance(0.7))
    second = add_distractor_truss(P, world, rng);
  if (P.room) add_room(P.name, mean, world);
  add_pedicel_leaves(T, world, leaf);
  return second;
}

void write_truth(const Truss& T, Scene& scene, const std::vector<TrussTomato>& distractors) {
  auto& tr = scene.truth;
  std::vector<double> centres, radii, dirs, anchors, forces, contacts, shapes;
  for (const auto& t : T.tomatoes) {
    shapes.insert(shapes.end(), {t.equatorial_radius_m, t.polar_radius_m, t.rib_amplitude});
    centres.insert(centres.end(), {t.centre_m.x(), t.centre_m.y(), t.centre_m.z()});
    radii.push_back(t.radius_m);
    dirs.insert(dirs.end(), {t.pedicel_dir.x(), t.pedicel_dir.y(), t.pedicel_dir.z()});
    anchors.insert(anchors.end(), {t.anchor_m.x(), t.anchor_m.y(), t.anchor_m.z()});
    forces.insert(forces.end(), {t.pedicel_force_n.x(), t.pedicel_force_n.y(), t.pedicel_force_n.z()});
  }
  for (const auto& c : T.contacts)
    contacts.insert(contacts.end(), {double(c.i), double(c.j), double(int(c.kind)), c.force_n});
  tr["truss_tomato_centres_m"] = centres;
  tr["truss_tomato_radii_m"] = radii;
  tr["truss_tomato_shapes_m"] = shapes;
  tr["truss_pedicel_dirs"] = dirs;
  tr["truss_pedicel_anchors_m"] = anchors;
  tr["truss_pedicel_forces_n"] = forces;
  tr["truss_contacts"] = contacts;
  const Eigen::Quaterniond q(T.T_world_camera.linear());
  const Eigen::Vector3d t = T.T_world_camera.translation();
  tr["truss_camera_pose"] = {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
  tr["truss_class"] = {static_cast<double>(static_cast<char>(T.params.complexity) - 'A')};
  tr["truss_seed"] = {static_cast<double>(T.params.seed)};
  std::vector<double> second;
  for (const auto& d : distractors) second.insert(second.end(), {d.centre_m.x(), d.centre_m.y(), d.centre_m.z()});
  tr["truss_distractor_centres_m"] = second;
  if (std::any_of(T.tomatoes.begin(), T.tomatoes.end(),
                  [](const TrussTomato& t) { return t.pedicel_path_m.size() > 2; })) {
    std::vector<double> counts, paths;
    for (const auto& t : T.tomatoes) {
      counts.push_back(double(t.pedicel_path_m.size()));
      for (const auto& q : t.pedicel_path_m) paths.insert(paths.end(), {q.x(), q.y(), q.z()});
    }
    tr["truss_pedicel_path_counts"] = counts;
    tr["truss_pedicel_paths_m"] = paths;
  }
}

namespace {

// The pedicels' paths when the truth has them; straight anchor -> calyx
// otherwise (the calyx: polar radius from the centre along the pedicel).
void read_pedicel_paths(const Scene& scene, std::vector<TrussTomato>& tomatoes) {
  const auto counts = scene.truth.find("truss_pedicel_path_counts");
  const auto paths = scene.truth.find("truss_pedicel_paths_m");
  if (counts == scene.truth.end() || paths == scene.truth.end()) {
    for (auto& t : tomatoes) t.pedicel_path_m = {t.anchor_m, t.centre_m + t.polar_radius_m * t.pedicel_dir};
    return;
  }
  if (counts->second.size() != tomatoes.size())
    throw std::runtime_error("scene truth 'truss_pedicel_path_counts' has " + std::to_string(counts->second.size()) +
                             " numbers for " + std::to_string(tomatoes.size()) + " tomatoes");
  std::size_t at = 0;
  for (std::size_t i = 0; i < tomatoes.size(); ++i) {
    const double c = counts->second[i];
    if (!(c >= 2 && c <= 64 && c == std::floor(c)) || paths->second.size() < 3 * (at + std::size_t(c)))
      throw std::runtime_error("scene truth 'truss_pedicel_paths_m' does not hold the points its counts promise");
    for (std::size_t k = 0; k < std::size_t(c); ++k, ++at)
      tomatoes[i].pedicel_path_m.emplace_back(paths->second[3 * at], paths->second[3 * at + 1],
                                              paths->second[3 * at + 2]);
    tomatoes[i].calyx_m = tomatoes[i].pedicel_path_m.back();
  }
  if (paths->second.size() != 3 * at)
    throw std::runtime_error("scene truth 'truss_pedicel_paths_m' has points left over");
}

}  // namespace

TrussTruth truss_truth_from_scene(const Scene& scene) {
  auto get = [&](const char* key, std::size_t multiple) -> const std::vector<double>& {
    const auto it = scene.truth.find(key);
    if (it == scene.truth.end())
      throw std::runtime_error(std::string("scene '") + scene.name + "' has no truth '" + key + "'");
    if (multiple == 0 ? it->second.empty() : it->second.size() % multiple != 0)
      throw std::runtime_error(std::string("scene truth '") + key + "' has " + std::to_string(it->second.size()) +
                               " numbers, not a multiple of " + std::to_string(multiple));
    return it->second;
  };
  TrussTruth out;
  const auto& radii = get("truss_tomato_radii_m", 1);
  const auto& centres = get("truss_tomato_centres_m", 3);
  const auto& dirs = get("truss_pedicel_dirs", 3);
  const auto& anchors = get("truss_pedicel_anchors_m", 3);
  const auto& forces = get("truss_pedicel_forces_n", 3);
  const std::size_t n = radii.size();
  if (centres.size() != 3 * n || dirs.size() != 3 * n || anchors.size() != 3 * n || forces.size() != 3 * n)
    throw std::runtime_error("scene truth: tomato entries disagree on the number of tomatoes");
  for (std::size_t i = 0; i < n; ++i) {
    TrussTomato t;
    t.centre_m = {centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]};
    t.radius_m = radii[i];
    t.pedicel_dir = {dirs[3 * i], dirs[3 * i + 1], dirs[3 * i + 2]};
    t.anchor_m = {anchors[3 * i], anchors[3 * i + 1], anchors[3 * i + 2]};
    t.pedicel_force_n = {forces[3 * i], forces[3 * i + 1], forces[3 * i + 2]};
    if (const auto it = scene.truth.find("truss_tomato_shapes_m");
        it != scene.truth.end() && it->second.size() == 3 * n) {
      t.equatorial_radius_m = it->second[3 * i];
      t.polar_radius_m = it->second[3 * i + 1];
      t.rib_amplitude = it->second[3 * i + 2];
    } else {
      t.equatorial_radius_m = t.polar_radius_m = t.radius_m;
    }
    out.tomatoes.push_back(t);
  }
  if (scene.truth.count("truss_contacts")) {
    const auto& c = get("truss_contacts", 4);
    for (std::size_t k = 0; k + 4 <= c.size(); k += 4) {
      const int kind = static_cast<int>(c[k + 2]);
      if (kind < 0 || kind > 2)
        throw std::runtime_error("scene truth 'truss_contacts': unknown contact kind " + std::to_string(kind));
      out.contacts.push_back(
          {static_cast<int>(c[k]), static_cast<int>(c[k + 1]), static_cast<ContactKind>(kind), c[k + 3]});
    }
  }
  read_pedicel_paths(scene, out.tomatoes);
  const auto& pose = get("truss_camera_pose", 7);
  if (pose.size() != 7) throw std::runtime_error("scene truth 'truss_camera_pose' must hold 7 numbers");
  out.T_world_camera =
      pose_from({pose[0], pose[1], pose[2]},
                Eigen::Quaterniond(pose[6], pose[3], pose[4], pose[5]).normalized().toRotationMatrix());
  const auto& cls = get("truss_class", 1);
  out.complexity = static_cast<TrussClass>('A' + static_cast<int>(cls[0]));
  out.seed = static_cast<std::uint64_t>(get("truss_seed", 1)[0]);
  if (const auto it = scene.truth.find("truss_distractor_centres_m"); it != scene.truth.end()) {
    for (std::size_t k = 0; k + 3 <= it->second.size(); k += 3)
      out.distractor_centres_m.emplace_back(it->second[k], it->second[k + 1], it->second[k + 2]);
  }
  return out;
}

TrussWorld make_truss_world(const TrussParams& params) {
  TrussWorld t{make_truss(params), World(), {}};
  t.distractors = add_to_world(t.truss, t.world);
  return t;
}

Scene make_truss_scene(const TrussParams& params) {
  Scene s;
  s.name = params.name + "_" + static_cast<char>(params.complexity) + "_" + std::to_string(params.seed);
  s.description = "tomato truss, complexity class " + std::string(1, static_cast<char>(params.complexity));
  TrussWorld t = make_truss_world(params);
  s.world = std::move(t.world);
  write_truth(t.truss, s, t.distractors);
  return s;
}

}  // namespace tinyline::sim

namespace {

void make_truss_from_yaml(const tinyline::sim::YamlNode& p, tinyline::sim::Scene& scene) {
  using namespace tinyline::sim;
  p.check_keys({"type", "name", "class", "seed", "num_tomatoes", "origin", "front_leaves", "background_leaves",
                "distractor_truss", "room", "camera_distance_m", "camera_jitter_m", "physics", "stem_bend_deg",
                "peduncle_curl_deg", "pedicel_leaves", "rest_tilt_max_deg"});
  TrussParams t;
  t.name = p.get_string("name", "truss");
  if (auto c = p.find("class")) {
    const auto cls = parse_truss_class(c->as_string());
    if (!cls) c->fail("class must be A, B or C (thesis Figure 4.8), got '" + c->as_string() + "'");
    t.complexity = *cls;
  }
  if (auto s = p.find("seed")) {
    const int seed = s->as_int();
    if (seed < 0) s->fail("seed must be >= 0");
    t.seed = static_cast<std::uint64_t>(seed);
  }
  t.num_tomatoes = static_cast<int>(p.in_range("num_tomatoes", 0, 0, 8));
  if (auto o = p.find("origin")) t.origin_m = o->as_vec3();
  t.front_leaves = static_cast<int>(p.in_range("front_leaves", -1, -1, 8));
  t.background_leaves = p.get_bool("background_leaves", true);
  t.distractor_truss = p.get_bool("distractor_truss", true);
  t.room = p.get_bool("room", true);
  t.camera_distance_m = p.in_range("camera_distance_m", t.camera_distance_m, 0.2, 2.0);
  t.camera_jitter_m = p.in_range("camera_jitter_m", t.camera_jitter_m, 0.0, 0.5);
  if (auto ph = p.find("physics")) {
    const auto v = parse_truss_physics(ph->as_string());
    if (!v) ph->fail("physics must be pendulum or elastic_rod, got '" + ph->as_string() + "'");
    t.physics = *v;
  }
  t.stem_bend_deg = p.in_range("stem_bend_deg", 0.0, -120.0, 120.0);
  t.peduncle_curl_deg = p.in_range("peduncle_curl_deg", 0.0, -180.0, 180.0);
  t.pedicel_leaves = static_cast<int>(p.in_range("pedicel_leaves", 0, 0, 8));
  t.rest_tilt_max_deg = p.in_range("rest_tilt_max_deg", t.rest_tilt_max_deg, 0.0, 80.0);
  try {
    const Truss truss = make_truss(t);
    const auto second = add_to_world(truss, scene.world);
    write_truth(truss, scene, second);
  } catch (const std::invalid_argument& e) {
    p.fail(e.what());
  }
}

}  // namespace

TINYLINE_SIM_SCENE_GENERATOR(truss) {
  registry.add("truss",
               "a tomato truss in static equilibrium (thesis 4.5 classes A/B/C): class, seed, num_tomatoes, origin, "
               "front_leaves, background_leaves, distractor_truss, room, camera_distance_m, camera_jitter_m, physics "
               "(pendulum | elastic_rod), stem_bend_deg, peduncle_curl_deg, pedicel_leaves, rest_tilt_max_deg",
               &make_truss_from_yaml);
}
