// SPDX-License-Identifier: Apache-2.0
#include "sim/scenes/truss_close.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace tinyline::sim {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

MaterialId material(const World& w, const std::string& name) { return sim::material(w, name, "close truss"); }

// A pedicel hanging from `top` (down = +y) within max_tilt of vertical, with its tomato.
HangingTomato hang(SceneRng& rng, const Eigen::Vector3d& top, const CloseTrussParams& o) {
  HangingTomato h;
  const double tilt = rng.uniform(0.0, o.max_tilt_deg) * kDeg, az = rng.uniform(0.0, 2.0 * std::numbers::pi);
  h.dir = Eigen::Vector3d(std::sin(tilt) * std::cos(az), std::cos(tilt), std::sin(tilt) * std::sin(az));
  h.length = rng.uniform(o.pedicel_length_m);
  h.radius = rng.uniform(o.pedicel_radius_m);
  h.top = top;
  h.bottom = top + h.length * h.dir;
  h.tomato_radius = rng.uniform(o.tomato_radius_m);
  h.tomato_centre = h.bottom + h.tomato_radius * h.dir;
  return h;
}

bool overlaps(const HangingTomato& a, const std::vector<HangingTomato>& others) {
  for (const auto& b : others) {
    if ((a.tomato_centre - b.tomato_centre).norm() < a.tomato_radius + b.tomato_radius + 0.002) return true;
    // The new pedicel must not run through an existing tomato, nor its tomato through a pedicel.
    for (const auto& [p, s] : {std::pair{&a, &b}, std::pair{&b, &a}}) {
      const Eigen::Vector3d d = p->bottom - p->top;
      const double t = std::clamp((s->tomato_centre - p->top).dot(d) / d.squaredNorm(), 0.0, 1.0);
      if ((p->top + t * d - s->tomato_centre).norm() < s->tomato_radius + p->radius) return true;
    }
  }
  return false;
}

// The curved stem's offset of a pedicel top dx along the stem from the
// target's (CloseTrussParams::stem_bow_m), across the stem at angle psi in y-z.
Eigen::Vector3d bow(const CloseTrussParams& o, double psi, double dx) {
  const double a = o.stem_bow_m * (dx / 0.1) * (dx / 0.1);
  return {0.0, a * std::cos(psi), a * std::sin(psi)};
}

// The target, moved so that the point `along` down its axis lies on the plane at `crossing`.
HangingTomato place_target(SceneRng& rng, const Eigen::Vector3d& crossing, const CloseTrussParams& o) {
  HangingTomato target = hang(rng, Eigen::Vector3d::Zero(), o);
  const double along = std::clamp(0.5 * target.length + rng.uniform(-o.vertical_jitter_m, o.vertical_jitter_m),
                                  0.2 * target.length, 0.8 * target.length);
  const Eigen::Vector3d shift = crossing - along * target.dir;
  target.top += shift;
  target.bottom += shift;
  target.tomato_centre += shift;
  return target;
}

// Neighbours along the stem on both sides (at least one in all).
void add_neighbours(SceneRng& rng, double psi, const CloseTrussParams& o, std::vector<HangingTomato>& hangings) {
  const HangingTomato target = hangings.front();  // a copy: the vector grows below
  int left = rng.integer(0, 2), right = rng.integer(0, 2);
  if (left + right == 0) (rng.integer(0, 1) ? left : right) = 1;
  for (const int side : {-1, 1}) {
    double x = target.top.x();
    for (int k = 0; k < (side < 0 ? left : right); ++k) {
      // Tomatoes do not interpenetrate: a crowded draw is redrawn, a little
      // further out each time.
      for (int attempt = 0; attempt < 50; ++attempt) {
        const double x_try = x + side * rng.uniform(o.neighbour_spacing_m) * (1.0 + 0.02 * attempt);
        Eigen::Vector3d top(x_try, target.top.y() + rng.uniform(-o.neighbour_drop_m, o.neighbour_drop_m),
                            target.top.z() + rng.uniform(-o.neighbour_depth_m, o.neighbour_depth_m));
        if (o.stem_bow_m != 0.0) top += bow(o, psi, x_try - target.top.x());
        const HangingTomato h = hang(rng, top, o);
        if (!overlaps(h, hangings)) {
          hangings.push_back(h);
          x = x_try;
          break;
        }
      }
    }
  }
}

void add_hangings(World& w, std::vector<HangingTomato>& hangings) {
  const auto stem = material(w, "stem"), red = material(w, "tomato_red");
  for (std::size_t i = 0; i < hangings.size(); ++i) {
    HangingTomato& h = hangings[i];
    const std::string name = i == 0 ? "target" : "neighbour" + std::to_string(i);
    h.pedicel = w.add({name + "_pedicel", RodShape{h.top, h.bottom, h.radius}, Eigen::Isometry3d::Identity(), stem});
    h.tomato = w.add({name + "_tomato", SphereShape{h.tomato_radius}, pose(h.tomato_centre), red});
  }
}

// The truss's main stem (rachis) runs through every pedicel's top: a chain
// of rods in order along x, continued 10 cm beyond the outer tops. Returns
// the first rod.
ObjectId add_stem(World& w, double psi, const CloseTrussParams& o, const std::vector<HangingTomato>& hangings) {
  std::vector<Eigen::Vector3d> tops;
  for (const auto& h : hangings) tops.push_back(h.top);
  std::sort(tops.begin(), tops.end(), [](const auto& a, const auto& b) { return a.x() < b.x(); });
  const Eigen::Vector3d first = tops.front(), last = tops.back();
  tops.insert(tops.begin(), first - Eigen::Vector3d(0.10, 0.0, 0.0));
  tops.push_back(last + Eigen::Vector3d(0.10, 0.0, 0.0));
  if (o.stem_bow_m != 0.0) {  // the ends follow the bow
    const double x0 = hangings.front().top.x();
    tops.front() += bow(o, psi, first.x() - 0.10 - x0) - bow(o, psi, first.x() - x0);
    tops.back() += bow(o, psi, last.x() + 0.10 - x0) - bow(o, psi, last.x() - x0);
  }
  const auto stem = material(w, "stem");
  ObjectId first_rod = kNoObject;
  for (std::size_t i = 0; i + 1 < tops.size(); ++i) {
    const ObjectId id =
        w.add({"stem" + std::to_string(i), RodShape{tops[i], tops[i + 1], 0.004}, Eigen::Isometry3d::Identity(), stem});
    if (i == 0) first_rod = id;
  }
  return first_rod;
}

void add_leaf_wall(World& w, SceneRng& rng, double nominal_depth_m, const CloseTrussParams& o) {
  if (rng.uniform(0.0, 1.0) >= o.leaf_probability) return;
  const Eigen::Matrix3d R = rot(Eigen::Vector3d::UnitY(), rng.uniform(-20.0, 20.0) * kDeg) *
                            rot(Eigen::Vector3d::UnitX(), rng.uniform(-20.0, 20.0) * kDeg);
  w.add({"leaf", PlaneShape{Eigen::Vector2d(0.6, 0.6)},
         pose(Eigen::Vector3d(rng.uniform(-0.1, 0.1), 0.0, nominal_depth_m + rng.uniform(o.leaf_z_m) - 0.15), R),
         material(w, "leaf")});
}

}  // namespace

CloseTruss add_close_truss(World& world, SceneRng& rng, std::uint64_t seed, const Eigen::Vector3d& crossing_m,
                           double nominal_depth_m, const CloseTrussParams& p) {
  CloseTruss t;
  t.hangings.push_back(place_target(rng, crossing_m, p));
  const double psi = p.stem_bow_m != 0.0 ? SceneRng(seed ^ 0x5bd1e995ULL).uniform(0.0, 2.0 * std::numbers::pi) : 0.0;
  add_neighbours(rng, psi, p, t.hangings);
  add_hangings(world, t.hangings);
  t.stem = add_stem(world, psi, p, t.hangings);
  add_leaf_wall(world, rng, nominal_depth_m, p);
  return t;
}

}  // namespace tinyline::sim
