// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/sequencer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>

#include <fmt/format.h>

namespace tinyline::hydrus_fitting {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kEps = 1e-9;

double dist_to_segment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0.0 ? std::clamp((p - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

}  // namespace

double ray_circle(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& c, double r) {
  const Eigen::Vector2d oc = o - c;
  const double b = oc.dot(d);
  const double cc = oc.squaredNorm() - r * r;
  const double disc = b * b - cc;
  if (disc < 0.0) return kInf;
  const double s = std::sqrt(disc);
  const double t0 = -b - s, t1 = -b + s;
  if (t0 > kEps) return t0;
  if (t1 > kEps) return t1;
  return kInf;
}

double ray_segment(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& p,
                   const Eigen::Vector2d& q) {
  const Eigen::Vector2d e = q - p;
  const double den = d.x() * e.y() - d.y() * e.x();
  if (std::abs(den) < 1e-15) return kInf;
  const Eigen::Vector2d w = p - o;
  const double t = (w.x() * e.y() - w.y() * e.x()) / den;
  const double u = (w.x() * d.y() - w.y() * d.x()) / den;
  if (t > kEps && u >= 0.0 && u <= 1.0) return t;
  return kInf;
}

bool inside_capsule(const Eigen::Vector2d& p, const Capsule& c) {
  return dist_to_segment(p, c.a_m, c.b_m) < c.half_width_m;
}

double ray_capsule(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Capsule& c) {
  double t = std::min(ray_circle(o, d, c.a_m, c.half_width_m), ray_circle(o, d, c.b_m, c.half_width_m));
  const Eigen::Vector2d ab = c.b_m - c.a_m;
  const double len = ab.norm();
  if (len > 0.0) {
    const Eigen::Vector2d nrm = Eigen::Vector2d(-ab.y(), ab.x()) / len * c.half_width_m;
    t = std::min(t, ray_segment(o, d, c.a_m + nrm, c.b_m + nrm));
    t = std::min(t, ray_segment(o, d, c.a_m - nrm, c.b_m - nrm));
  }
  return t;
}

namespace {

/// Occluders prepared for one ray origin: the ones containing it are skipped
/// (a sensor sits on its own link; light leaves it).
struct Scene2D {
  std::vector<Circle> circles;
  std::vector<Capsule> capsules;

  double first_hit(const Eigen::Vector2d& o, const Eigen::Vector2d& d) const {
    double t = kInf;
    for (const auto& c : circles)
      if ((o - c.centre_m).norm() >= c.radius_m) t = std::min(t, ray_circle(o, d, c.centre_m, c.radius_m));
    for (const auto& c : capsules)
      if (!inside_capsule(o, c)) t = std::min(t, ray_capsule(o, d, c));
    return t;
  }
  /// Line of sight from o to q (q itself may lie on an occluder's surface).
  bool visible(const Eigen::Vector2d& o, const Eigen::Vector2d& q) const {
    const Eigen::Vector2d v = q - o;
    const double len = v.norm();
    if (len < kEps) return true;
    return first_hit(o, v / len) >= len - 1e-6;
  }
};

double wrap(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

bool in_view(const SensorView2D& s, const Eigen::Vector2d& q, double margin) {
  const Eigen::Vector2d v = q - s.origin_m;
  const double r = v.norm();
  if (r < kEps || r > s.range_m) return false;
  return std::abs(wrap(std::atan2(v.y(), v.x()) - s.yaw_rad)) <= s.fov_half_angle_rad + margin;
}

/// A point lit by emitter j that receiver i sees, if any.
std::optional<Eigen::Vector2d> conflict_witness(const SensorView2D& i_rx, const SensorView2D& j_tx,
                                                const Scene2D& scene, const InterferenceParams& p) {
  const double margin = p.angle_margin_rad;
  // Direct: j's emitter in i's view and i inside j's fan, line of sight free.
  {
    const Eigen::Vector2d v = i_rx.origin_m - j_tx.origin_m;
    const double r = v.norm();
    if (r > kEps && r <= j_tx.range_m &&
        std::abs(wrap(std::atan2(v.y(), v.x()) - j_tx.yaw_rad)) <= j_tx.fan_half_angle_rad + margin &&
        in_view(i_rx, j_tx.origin_m, margin) && scene.visible(j_tx.origin_m, i_rx.origin_m)) {
      return j_tx.origin_m;
    }
  }
  const int k = std::max(2, p.rays_per_fan);
  const double half = j_tx.fan_half_angle_rad + margin;
  for (int r = 0; r < k; ++r) {
    const double a = j_tx.yaw_rad - half + 2.0 * half * r / (k - 1);
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    const double t_hit = scene.first_hit(j_tx.origin_m, d);
    if (t_hit <= j_tx.range_m) {
      // Lights a known surface; the way there is known free space.
      const Eigen::Vector2d q = j_tx.origin_m + t_hit * d;
      if (in_view(i_rx, q, margin) && scene.visible(i_rx.origin_m, q)) return q;
      continue;
    }
    // Nothing known on the ray: something unknown may stand anywhere on it.
    const double step = std::max(1e-3, p.step_m);
    for (double t = step; t <= j_tx.range_m + 1e-12; t += step) {
      const Eigen::Vector2d q = j_tx.origin_m + t * d;
      if (in_view(i_rx, q, margin) && scene.visible(i_rx.origin_m, q)) return q;
    }
  }
  return std::nullopt;
}

}  // namespace

std::vector<SensorView2D> sensor_views(const RobotModel& model, const Kinematics& k) {
  std::vector<SensorView2D> v;
  v.reserve(model.sensors().size());
  for (std::size_t i = 0; i < model.sensors().size(); ++i) {
    const auto& s = model.sensors()[i];
    const auto& T = k.T_base_sensor[i];
    SensorView2D sv;
    sv.origin_m = T.translation();
    sv.yaw_rad = Eigen::Rotation2Dd(T.linear()).angle();
    sv.fov_half_angle_rad = s.fov_half_angle_rad();
    sv.fan_half_angle_rad = s.fan_half_angle_rad;
    sv.range_m = s.max_range_m;
    v.push_back(sv);
  }
  return v;
}

std::vector<Capsule> link_capsules(const RobotModel& model, const Kinematics& k) {
  std::vector<Capsule> c;
  for (std::size_t i = 0; i < model.links().size(); ++i) {
    const auto& l = model.links()[i];
    const auto& T = k.T_base_link[i];
    c.push_back({T.translation(), T * Eigen::Vector2d(l.length_m, 0.0), 0.5 * l.width_m});
  }
  return c;
}

int InterferenceGraph::edges() const {
  int e = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) e += conflict(i, j);
  return e;
}

InterferenceGraph interference_graph(std::span<const SensorView2D> sensors, const Occluders& occluders,
                                     const InterferenceParams& params) {
  InterferenceGraph g;
  g.n = static_cast<int>(sensors.size());
  const auto nn = static_cast<std::size_t>(g.n * g.n);
  g.adjacency.assign(nn, 0);
  g.witness_m.assign(nn, Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  Scene2D scene;
  for (const auto& c : occluders.circles) {
    const double r = c.radius_m - params.occluder_shrink_m;
    if (r > 0.0) scene.circles.push_back({c.centre_m, r});
  }
  scene.capsules = occluders.capsules;
  for (int i = 0; i < g.n; ++i) {
    for (int j = 0; j < g.n; ++j) {
      if (i == j) continue;
      const auto w =
          conflict_witness(sensors[static_cast<std::size_t>(i)], sensors[static_cast<std::size_t>(j)], scene, params);
      if (!w) continue;
      // Conflicts are symmetric for scheduling: neither may emit while the other integrates.
      g.adjacency[static_cast<std::size_t>(i * g.n + j)] = g.adjacency[static_cast<std::size_t>(j * g.n + i)] = 1;
      g.witness_m[static_cast<std::size_t>(i * g.n + j)] = *w;
    }
  }
  return g;
}

InterferenceGraph graph_from_edges(int n, std::span<const std::pair<int, int>> edges) {
  if (n < 0) throw std::invalid_argument("graph_from_edges: n must be >= 0");
  InterferenceGraph g;
  g.n = n;
  g.adjacency.assign(static_cast<std::size_t>(n * n), 0);
  g.witness_m.assign(static_cast<std::size_t>(n * n),
                     Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (const auto& [a, b] : edges) {
    if (a < 0 || b < 0 || a >= n || b >= n || a == b)
      throw std::invalid_argument(fmt::format("graph_from_edges: bad edge ({}, {}) for {} vertices", a, b, n));
    g.adjacency[static_cast<std::size_t>(a * n + b)] = g.adjacency[static_cast<std::size_t>(b * n + a)] = 1;
  }
  return g;
}

// ---------------------------------------------------------------------------- colouring

namespace {

/// DSatur: colour the vertex with the most distinct neighbour colours next.
Colouring dsatur(const InterferenceGraph& g) {
  Colouring c;
  c.colour.assign(static_cast<std::size_t>(g.n), -1);
  for (int step = 0; step < g.n; ++step) {
    int best = -1, best_sat = -1, best_deg = -1;
    for (int v = 0; v < g.n; ++v) {
      if (c.colour[static_cast<std::size_t>(v)] >= 0) continue;
      std::vector<char> seen(static_cast<std::size_t>(g.n + 1), 0);
      int sat = 0, deg = 0;
      for (int u = 0; u < g.n; ++u) {
        if (!g.conflict(v, u)) continue;
        ++deg;
        const int cu = c.colour[static_cast<std::size_t>(u)];
        if (cu >= 0 && !seen[static_cast<std::size_t>(cu)]) {
          seen[static_cast<std::size_t>(cu)] = 1;
          ++sat;
        }
      }
      if (sat > best_sat || (sat == best_sat && deg > best_deg)) {
        best = v;
        best_sat = sat;
        best_deg = deg;
      }
    }
    int col = 0;
    for (;; ++col) {
      bool used = false;
      for (int u = 0; u < g.n && !used; ++u) used = g.conflict(best, u) && c.colour[static_cast<std::size_t>(u)] == col;
      if (!used) break;
    }
    c.colour[static_cast<std::size_t>(best)] = col;
    c.colours = std::max(c.colours, col + 1);
  }
  return c;
}

/// Exact: can the graph be coloured with k colours? Backtracking in a fixed
/// order (decreasing degree), symmetry broken by opening colours in order.
bool colour_k(const InterferenceGraph& g, const std::vector<int>& order, std::size_t pos, int k, int opened,
              std::vector<int>& colour, long long& budget) {
  if (pos == order.size()) return true;
  if (--budget < 0) return false;
  const int v = order[pos];
  for (int c = 0; c < std::min(k, opened + 1); ++c) {
    bool ok = true;
    for (int u = 0; u < g.n && ok; ++u) ok = !(g.conflict(v, u) && colour[static_cast<std::size_t>(u)] == c);
    if (!ok) continue;
    colour[static_cast<std::size_t>(v)] = c;
    if (colour_k(g, order, pos + 1, k, std::max(opened, c + 1), colour, budget)) return true;
    colour[static_cast<std::size_t>(v)] = -1;
  }
  return false;
}

}  // namespace

Colouring colour_graph(const InterferenceGraph& g, int exact_limit) {
  if (g.n == 0) return {{}, 0, true};
  Colouring best = dsatur(g);
  if (g.n > exact_limit) return best;
  std::vector<int> order(static_cast<std::size_t>(g.n));
  std::iota(order.begin(), order.end(), 0);
  auto degree = [&](int v) {
    int d = 0;
    for (int u = 0; u < g.n; ++u) d += g.conflict(v, u);
    return d;
  };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return degree(a) > degree(b); });
  long long budget = 2'000'000;  // bounded effort; the sizes of a robot finish far below it
  for (int k = 1; k < best.colours; ++k) {
    std::vector<int> colour(static_cast<std::size_t>(g.n), -1);
    if (colour_k(g, order, 0, k, 0, colour, budget)) {
      best.colour = colour;
      best.colours = k;
      best.optimal = true;
      return best;
    }
    if (budget < 0) return best;  // gave up: DSatur's answer, not proven
  }
  best.optimal = true;  // no smaller k works
  return best;
}

// ---------------------------------------------------------------------------- schedules

bool Schedule::emits(int slot, int sensor) const {
  const auto& s = slots.at(static_cast<std::size_t>(slot));
  return std::binary_search(s.begin(), s.end(), sensor);
}

double Schedule::min_rate_hz() const {
  return rate_hz.empty() ? 0.0 : *std::min_element(rate_hz.begin(), rate_hz.end());
}

namespace {
void fill_rates(Schedule& s, int n) {
  s.rate_hz.assign(static_cast<std::size_t>(n), 0.0);
  if (s.slots.empty()) return;
  for (const auto& slot : s.slots)
    for (const int v : slot) s.rate_hz[static_cast<std::size_t>(v)] += 1.0;
  for (auto& r : s.rate_hz) r /= s.cycle_s();
}
}  // namespace

Schedule time_slicing_schedule(int n, const SlotTiming& timing) {
  Schedule s;
  s.name = "time_slicing";
  s.timing = timing;
  for (int i = 0; i < n; ++i) s.slots.push_back({i});
  fill_rates(s, n);
  return s;
}

Schedule colouring_schedule(const InterferenceGraph& g, const Colouring& c, const SlotTiming& timing, bool fill) {
  if (c.colour.size() != static_cast<std::size_t>(g.n))
    throw std::invalid_argument(fmt::format("colouring has {} entries for {} sensors", c.colour.size(), g.n));
  Schedule s;
  s.name = "colouring";
  s.timing = timing;
  s.slots.resize(static_cast<std::size_t>(c.colours));
  for (int v = 0; v < g.n; ++v) s.slots[static_cast<std::size_t>(c.colour[static_cast<std::size_t>(v)])].push_back(v);
  if (fill) {
    // Sensors with the fewest slots first, so the slowest gain first.
    std::vector<int> count(static_cast<std::size_t>(g.n), 1);
    std::vector<int> order(static_cast<std::size_t>(g.n));
    std::iota(order.begin(), order.end(), 0);
    for (auto& members : s.slots) {
      std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
        return count[static_cast<std::size_t>(a)] < count[static_cast<std::size_t>(b)];
      });
      for (const int v : order) {
        if (std::find(members.begin(), members.end(), v) != members.end()) continue;
        if (std::none_of(members.begin(), members.end(), [&](int u) { return g.conflict(v, u); })) {
          members.push_back(v);
          ++count[static_cast<std::size_t>(v)];
        }
      }
    }
  }
  for (auto& slot : s.slots) std::sort(slot.begin(), slot.end());
  fill_rates(s, g.n);
  return s;
}

Schedule with_always_emitting(Schedule s, std::span<const int> always) {
  if (always.empty() || s.slots.empty()) return s;
  const int n = static_cast<int>(s.rate_hz.size());
  auto is_always = [&](int v) { return std::find(always.begin(), always.end(), v) != always.end(); };
  // A slot that only held sensors which emit anyway gives nobody else time: drop it.
  std::vector<std::vector<int>> kept;
  for (auto& slot : s.slots) {
    if (!std::all_of(slot.begin(), slot.end(), is_always)) kept.push_back(std::move(slot));
  }
  if (kept.empty()) kept.emplace_back();
  for (auto& slot : kept) {
    for (const int v : always) {
      if (v >= 0 && v < n && !std::binary_search(slot.begin(), slot.end(), v))
        slot.insert(std::upper_bound(slot.begin(), slot.end(), v), v);
    }
  }
  s.slots = std::move(kept);
  fill_rates(s, n);
  return s;
}

common::Status check_schedule(const InterferenceGraph& g, const Schedule& s) {
  std::vector<int> seen(static_cast<std::size_t>(g.n), 0);
  for (std::size_t k = 0; k < s.slots.size(); ++k) {
    const auto& m = s.slots[k];
    for (std::size_t a = 0; a < m.size(); ++a) {
      if (m[a] < 0 || m[a] >= g.n)
        return common::Status::invalid(fmt::format("slot {} holds sensor {} of {}", k, m[a], g.n));
      ++seen[static_cast<std::size_t>(m[a])];
      for (std::size_t b = a + 1; b < m.size(); ++b)
        if (g.conflict(m[a], m[b]))
          return common::Status::invalid(fmt::format("slot {}: sensors {} and {} conflict", k, m[a], m[b]));
    }
  }
  for (int v = 0; v < g.n; ++v)
    if (!seen[static_cast<std::size_t>(v)]) return common::Status::invalid(fmt::format("sensor {} never emits", v));
  return {};
}

// ---------------------------------------------------------------------------- Sequencer

Sequencer::Sequencer(const RobotModel& model, SequencerParams params) : model_(&model), params_(params) {}

bool Sequencer::update(std::span<const double> joint_positions, const std::optional<Circle>& object) {
  const Kinematics k = model_->forward(joint_positions);
  std::vector<SensorView2D> views = sensor_views(*model_, k);
  bool rebuild = !built_;
  if (!rebuild) {
    for (std::size_t i = 0; i < views.size() && !rebuild; ++i) {
      rebuild = (views[i].origin_m - last_views_[i].origin_m).norm() > params_.recompute_translation_m ||
                std::abs(wrap(views[i].yaw_rad - last_views_[i].yaw_rad)) > params_.recompute_rotation_rad;
    }
    if (object.has_value() != last_object_.has_value()) {
      rebuild = true;
    } else if (object) {
      rebuild = rebuild || (object->centre_m - last_object_->centre_m).norm() > params_.recompute_object_m ||
                std::abs(object->radius_m - last_object_->radius_m) > params_.recompute_object_m;
    }
  }
  if (!rebuild) return false;
  Occluders occ;
  if (object) occ.circles.push_back(*object);
  if (params_.links_occlude) occ.capsules = link_capsules(*model_, k);
  InterferenceGraph g = interference_graph(views, occ, params_.interference);
  last_views_ = std::move(views);
  last_object_ = object;
  ++rebuilds_;
  const bool changed = !built_ || g.adjacency != graph_.adjacency;
  built_ = true;
  graph_ = std::move(g);
  if (changed) {
    colouring_ = colour_graph(graph_);
    schedule_ = colouring_schedule(graph_, colouring_, params_.timing, params_.fill);
  }
  return changed;
}

}  // namespace tinyline::hydrus_fitting
