// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/sphere_ransac.hpp"

#include "tomato_reasoning/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Dense>

#include "voxel_hash.hpp"

#include <tinyline/common/least_squares.hpp>
#include <tinyline/common/random.hpp>

namespace tinyline::tomato_reasoning {

std::optional<Sphere> sphere_from_four_points(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                              const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  // Eq. 4.11: |p_i - c|^2 = r^2 for all four; subtracting the first leaves
  // the linear system 2 (p_i - p_0) . c = |p_i|^2 - |p_0|^2.
  Eigen::Matrix3d A;
  A.row(0) = 2.0 * (b - a);
  A.row(1) = 2.0 * (c - a);
  A.row(2) = 2.0 * (d - a);
  const double scale = A.row(0).norm() * A.row(1).norm() * A.row(2).norm();
  // Coplanar (or nearly): the system is singular relative to its size.
  if (!(scale > 0) || std::abs(A.determinant()) < 1e-3 * scale) return std::nullopt;
  const Eigen::Vector3d rhs(b.squaredNorm() - a.squaredNorm(), c.squaredNorm() - a.squaredNorm(),
                            d.squaredNorm() - a.squaredNorm());
  const Eigen::Vector3d centre = A.partialPivLu().solve(rhs);
  if (!centre.allFinite()) return std::nullopt;
  return Sphere{centre, (a - centre).norm()};
}

std::optional<Sphere> sphere_from_two_points_with_normals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                                          const Eigen::Vector3d& p2, const Eigen::Vector3d& n2) {
  // Eq. 4.12: the shortest segment between the lines p1 + s n1 and p2 + t n2.
  const Eigen::Vector3d w0 = p1 - p2;
  const double b = n1.dot(n2), d = n1.dot(w0), e = n2.dot(w0);
  const double denom = n1.squaredNorm() * n2.squaredNorm() - b * b;
  if (!(denom > 1e-6)) return std::nullopt;  // parallel normals: no centre
  const double s = (b * e - n2.squaredNorm() * d) / denom;
  const double t = (n1.squaredNorm() * e - b * d) / denom;
  const Eigen::Vector3d centre = 0.5 * ((p1 + s * n1) + (p2 + t * n2));
  if (!centre.allFinite()) return std::nullopt;
  return Sphere{centre, 0.5 * ((p1 - centre).norm() + (p2 - centre).norm())};
}

const char* to_string(SphereHypothesis h) {
  return h == SphereHypothesis::kFourPoints ? "four_points" : "two_points_with_normals";
}

namespace {

// sum (|p - c| - r)^2 over the centre c (x = c), or over c and r (x = (c, r)).
struct SphereProblem {
  const std::vector<Eigen::Vector3f>& pts;
  const Indices& idx;
  bool fix_radius;
  double radius_m;  // the held radius when fix_radius

  Sphere sphere(const Eigen::VectorXd& x) const { return {x.head<3>(), fix_radius ? radius_m : x[3]}; }
  double cost_of(const Sphere& q) const {
    double e = 0;
    for (int k : idx) {
      const double r = (pts[static_cast<std::size_t>(k)].cast<double>() - q.centre).norm() - q.radius_m;
      e += r * r;
    }
    return e;
  }
  std::pair<Eigen::MatrixXd, Eigen::VectorXd> linearise(const Eigen::VectorXd& x) const {
    const Sphere s = sphere(x);
    Eigen::Matrix4d JtJ = Eigen::Matrix4d::Zero();
    Eigen::Vector4d Jte = Eigen::Vector4d::Zero();
    for (int k : idx) {
      const Eigen::Vector3d d = pts[static_cast<std::size_t>(k)].cast<double>() - s.centre;
      const double dist = d.norm();
      if (dist < 1e-12) continue;
      Eigen::Vector4d J;
      J << -d / dist, -1.0;
      const double res = dist - s.radius_m;
      JtJ += J * J.transpose();
      Jte += J * res;
    }
    const Eigen::Index np = x.size();
    return {JtJ.topLeftCorner(np, np), Jte.head(np)};
  }
  double cost(Eigen::VectorXd& candidate) const {
    const Sphere t = sphere(candidate);
    return t.centre.allFinite() && std::isfinite(t.radius_m) ? cost_of(t) : std::numeric_limits<double>::infinity();
  }
  void accept() const {}
  bool converged(double old_cost, double new_cost, const Eigen::VectorXd& step) const {
    return (old_cost - new_cost) / std::max(old_cost, 1e-30) < 1e-10 || step.norm() < 1e-9;
  }
};

// Levenberg-Marquardt from s on the sphere's squared distances.
SphereRefinement lm(const std::vector<Eigen::Vector3f>& pts, const Indices& idx, const Sphere& s, bool fix_radius) {
  SphereProblem problem{pts, idx, fix_radius, s.radius_m};
  Eigen::VectorXd x(fix_radius ? 3 : 4);
  x.head<3>() = s.centre;
  if (!fix_radius) x[3] = s.radius_m;
  common::LevenbergMarquardtSettings settings;
  settings.max_iterations = 50;
  settings.max_tries = 10;
  settings.initial_lambda = 1e-3;
  settings.increase = 10.0;
  settings.decrease = 0.3;
  settings.min_lambda = 1e-9;
  const common::LevenbergMarquardtResult r = common::levenberg_marquardt(problem, x, problem.cost_of(s), settings);
  SphereRefinement out;
  out.sphere = problem.sphere(x);
  out.iterations = r.iterations;
  out.converged = r.converged;
  out.rms_m = idx.empty() ? 0.0 : std::sqrt(r.cost / static_cast<double>(idx.size()));
  return out;
}

}  // namespace

SphereRefinement refine_sphere(const std::vector<Eigen::Vector3f>& points, const Indices& indices,
                               const Sphere& initial, double r_min, double r_max) {
  Sphere start = initial;
  start.radius_m = std::clamp(start.radius_m, r_min, r_max);
  SphereRefinement free = lm(points, indices, start, false);
  if (free.sphere.radius_m >= r_min && free.sphere.radius_m <= r_max) return free;
  // The free optimum leaves the range: hold the radius at the nearer limit.
  Sphere held = free.sphere;
  held.radius_m = free.sphere.radius_m < r_min ? r_min : r_max;
  held.centre = start.centre;
  SphereRefinement fixed = lm(points, indices, held, true);
  fixed.radius_at_limit = true;
  fixed.iterations += free.iterations;
  return fixed;
}

common::Status validate(const SphereRansacParams& p) {
  if (common::Status s = common::within_table(p); !s.ok()) return s;
  if (!(p.radius_max_m >= p.radius_min_m))
    return common::Status::invalid("radius range must satisfy radius_min_m <= radius_max_m");
  return {};
}

SphereSegmentation segment_spheres(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<Eigen::Vector3f>& normals, const SphereRansacParams& P,
                                   const Eigen::Vector3f& viewpoint) {
  return segment_spheres(points, normals, P, std::vector<Eigen::Vector3f>{viewpoint});
}

namespace {

// One run of the iterative RANSAC: the points, what is still alive, the
// accepted spheres; each step of a round is a method.
class SphereSegmenter {
 public:
  SphereSegmenter(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                  const SphereRansacParams& P, const std::vector<Eigen::Vector3f>& viewpoints, bool use_normals,
                  Indices alive_list, SphereSegmentation& out)
      : points_(points),
        normals_(normals),
        P_(P),
        use_normals_(use_normals),
        out_(out),
        alive_list_(std::move(alive_list)),
        alive_(points.size(), 0),
        thr_(P.inlier_distance_m),
        cos_tol_(P.normal_tolerance_deg > 0 ? std::cos(P.normal_tolerance_deg * M_PI / 180.0) : -2.0),
        r_lo_(P.radius_min_m - thr_),
        r_hi_(P.radius_max_m + thr_),
        reach_(2.0 * P.radius_max_m),  // a hypothesis's points lie within one diameter
        // Scoring looks only at cells that the sphere's shell can reach.
        grid_(points, alive_list_, std::max(0.01, P.radius_max_m / 2.0)),
        rng_(common::stream_seed(P.seed, 0x632be59bd9b4e019ULL)),
        k_points_(P.hypothesis == SphereHypothesis::kFourPoints ? 4 : 2) {
    for (int k : alive_list_) alive_[static_cast<std::size_t>(k)] = 1;
    for (const auto& v : viewpoints) eyes_.push_back(v.cast<double>());
  }

  void run() {
    int failed = 0;
    while (start_round()) {
      const Scored best = best_model_of_round();
      if (best.count < P_.min_inliers) {
        if (++failed >= P_.max_failed_rounds) {
          out_.stop_reason = std::to_string(failed) +
                             " round(s) without a model of >= " + std::to_string(P_.min_inliers) + " inliers (" +
                             std::to_string(out_.remaining_points) + " points left)";
          break;
        }
        continue;
      }
      if (!accept(best)) {
        // Refinement moved it somewhere unacceptable: drop its points from
        // sampling this round's way (keep them for others) by failing the round.
        if (++failed >= P_.max_failed_rounds) {
          out_.stop_reason =
              "the best models were refused (cap facing away or overlap) " + std::to_string(failed) + " times";
          break;
        }
        continue;
      }
      failed = 0;
    }
  }

 private:
  struct Scored {
    Sphere s;
    int count = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  };

  [[nodiscard]] Eigen::Vector3d pt(int k) const { return points_[static_cast<std::size_t>(k)].cast<double>(); }

  // Largest cosine between (q - c) and (eye - c) over the viewpoints: > 0 when
  // some camera sees the side of the sphere that q lies on.
  [[nodiscard]] double facing(const Eigen::Vector3d& q, const Eigen::Vector3d& c) const {
    double best = -2;
    const Eigen::Vector3d a = (q - c).normalized();
    for (const auto& e : eyes_) best = std::max(best, a.dot((e - c).normalized()));
    return best;
  }

  // Inliers of sphere s among the alive points (optionally listing them).
  Scored score(const Sphere& s, double dist_thr, Indices* list) const {
    Scored r;
    r.s = s;
    const float lim = static_cast<float>(s.radius_m + dist_thr);
    const Eigen::Vector3f c = s.centre.cast<float>();
    const detail::CellKey lo = grid_.key_of(c - Eigen::Vector3f::Constant(lim));
    const detail::CellKey hi = grid_.key_of(c + Eigen::Vector3f::Constant(lim));
    for (int x = lo.x; x <= hi.x; ++x)
      for (int y = lo.y; y <= hi.y; ++y)
        for (int z = lo.z; z <= hi.z; ++z) {
          const int cell = grid_.find({x, y, z});
          if (cell < 0) continue;
          for (const int* m = grid_.begin(std::size_t(cell)); m != grid_.end(std::size_t(cell)); ++m) {
            if (!is_inlier(*m, s, dist_thr)) continue;
            ++r.count;
            r.sum += pt(*m);
            if (list) list->push_back(*m);
          }
        }
    return r;
  }

  [[nodiscard]] bool is_inlier(int m, const Sphere& s, double dist_thr) const {
    const std::size_t k = static_cast<std::size_t>(m);
    if (!alive_[k]) return false;
    const Eigen::Vector3d d = points_[k].cast<double>() - s.centre;
    const double dist = d.norm();
    if (std::abs(dist - s.radius_m) > dist_thr || dist < 1e-9) return false;
    return !(use_normals_ && cos_tol_ > -1.5 && normals_[k].cast<double>().dot(d) < cos_tol_ * dist);
  }

  // Would this sphere be acceptable as a tomato here?
  bool plausible(const Scored& r, bool count_rejections) {
    if (r.count == 0) return false;
    const Eigen::Vector3d centroid = r.sum / r.count;
    if (facing(centroid, r.s.centre) <= 0) {  // the visible cap faces away from every camera
      if (count_rejections) ++out_.rejected_cap;
      return false;
    }
    for (const auto& f : out_.spheres) {
      if ((f.sphere.centre - r.s.centre).norm() < f.sphere.radius_m + r.s.radius_m - P_.max_overlap_m) {
        if (count_rejections) ++out_.rejected_overlap;
        return false;
      }
    }
    return true;
  }

  // Drops dead points from the sampling list; false (with the reason) when
  // no further round is due.
  bool start_round() {
    alive_list_.erase(std::remove_if(alive_list_.begin(), alive_list_.end(),
                                     [&](int k) { return !alive_[static_cast<std::size_t>(k)]; }),
                      alive_list_.end());
    out_.remaining_points = static_cast<int>(alive_list_.size());
    if (out_.remaining_points < P_.min_remaining) {
      out_.stop_reason =
          std::to_string(out_.remaining_points) + " points remain (< " + std::to_string(P_.min_remaining) + ")";
      return false;
    }
    if (static_cast<int>(out_.spheres.size()) >= P_.max_spheres) {
      out_.stop_reason = "max_spheres (" + std::to_string(P_.max_spheres) + ") reached";
      return false;
    }
    ++out_.rounds;
    return true;
  }

  // The other points of a sample: near the first (rejection sampling, a few
  // tries), or anywhere. False when none was found.
  bool draw_sample(int (&sample)[4]) {
    const std::size_t n_alive = alive_list_.size();
    const Eigen::Vector3d p0 = pt(sample[0]);
    for (int j = 1; j < k_points_; ++j) {
      bool found = false;
      for (int tries = 0; tries < 64 && !found; ++tries) {
        const int cand = alive_list_[rng_.index(n_alive)];
        if (cand == sample[0] || cand == sample[1] || cand == sample[2]) continue;
        if (P_.local_sampling && (pt(cand) - p0).norm() > reach_) continue;
        sample[j] = cand;
        found = true;
      }
      if (!found) return false;
    }
    return true;
  }

  // The sphere of a sample (Eq. 4.12 with normals, or through four points).
  [[nodiscard]] std::optional<Sphere> hypothesis(const int (&sample)[4]) const {
    if (k_points_ == 4) return sphere_from_four_points(pt(sample[0]), pt(sample[1]), pt(sample[2]), pt(sample[3]));
    const Eigen::Vector3d n0 = normals_[static_cast<std::size_t>(sample[0])].cast<double>();
    const Eigen::Vector3d n1 = normals_[static_cast<std::size_t>(sample[1])].cast<double>();
    std::optional<Sphere> s = sphere_from_two_points_with_normals(pt(sample[0]), n0, pt(sample[1]), n1);
    // Normals face the camera, so the centre must lie behind both points.
    if (s && ((pt(sample[0]) - s->centre).dot(n0) <= 0 || (pt(sample[1]) - s->centre).dot(n1) <= 0)) s.reset();
    if (s && std::abs((pt(sample[0]) - s->centre).norm() - (pt(sample[1]) - s->centre).norm()) > 2 * thr_) s.reset();
    return s;
  }

  // Eq. 4.13-4.15: samples needed for `confidence`, the first point drawn
  // from all alive points, the others (locally) from the model's neighbourhood.
  [[nodiscard]] long samples_needed(const Scored& best, long it, long needed) const {
    const double n_alive = static_cast<double>(alive_list_.size());
    double local_share = 0.5;
    if (P_.local_sampling) {
      int near = 0;
      grid_.for_each_within(points_, best.s.centre.cast<float>(), static_cast<float>(best.s.radius_m + reach_),
                            [&](int k) { near += alive_[static_cast<std::size_t>(k)]; });
      local_share = std::min(1.0, best.count / std::max(1.0, double(near)));
    } else {
      local_share = best.count / n_alive;
    }
    const double w = (best.count / n_alive) * std::pow(local_share, k_points_ - 1);
    if (w >= 1.0) return it + 1;
    if (w > 0)
      return std::min<long>(P_.max_iterations,
                            static_cast<long>(std::ceil(std::log(1.0 - P_.confidence) / std::log(1.0 - w))));
    return needed;
  }

  // The hypotheses of one round; the best plausible model.
  Scored best_model_of_round() {
    Scored best;
    long needed = P_.max_iterations;
    for (long it = 0; it < needed; ++it) {
      ++out_.hypotheses;
      int sample[4] = {alive_list_[rng_.index(alive_list_.size())], -1, -1, -1};
      std::optional<Sphere> s;
      if (draw_sample(sample)) s = hypothesis(sample);
      // The radius in range, and the first point on a visible half.
      if (!s || s->radius_m < r_lo_ || s->radius_m > r_hi_ || facing(pt(sample[0]), s->centre) <= 0) {
        ++out_.degenerate;
        continue;
      }
      const Scored r = score(*s, thr_, nullptr);
      if (r.count <= best.count || !plausible(r, false)) continue;
      best = r;
      needed = samples_needed(best, it, needed);
    }
    return best;
  }

  // Refines the round's best model on its inliers and, when still plausible,
  // accepts it and removes its fruit's points.
  bool accept(const Scored& best) {
    Indices inliers;
    (void)score(best.s, thr_, &inliers);
    Sphere model = best.s;
    bool at_limit = false;
    if (P_.refine) {
      const SphereRefinement ref = refine_sphere(points_, inliers, best.s, P_.radius_min_m, P_.radius_max_m);
      if (ref.sphere.centre.allFinite()) {
        model = ref.sphere;
        at_limit = ref.radius_at_limit;
      }
    }
    Indices final_inliers;
    const Scored fin = score(model, thr_, &final_inliers);
    if (fin.count < P_.min_inliers || !plausible(fin, true)) return false;
    double rms = 0;
    for (int k : final_inliers) {
      const double e = (pt(k) - model.centre).norm() - model.radius_m;
      rms += e * e;
    }
    SphereFit fit;
    fit.sphere = model;
    fit.inliers = final_inliers;
    fit.rms_m = std::sqrt(rms / std::max<std::size_t>(1, final_inliers.size()));
    fit.radius_at_limit = at_limit;
    fit.cap_facing = facing(fin.sum / fin.count, model.centre);
    fit.round = out_.rounds;
    remove_fruit(model);
    out_.spheres.push_back(std::move(fit));
    return true;
  }

  // Removes the fruit's points: its shell (a little wider than the inlier
  // band, normals agreeing) and anything inside it.
  void remove_fruit(const Sphere& model) {
    Indices removed;
    (void)score(model, P_.removal_factor * thr_, &removed);
    for (int k : removed) alive_[static_cast<std::size_t>(k)] = 0;
    const float rin = static_cast<float>(model.radius_m - thr_);
    grid_.for_each_within(points_, model.centre.cast<float>(), std::max(0.0f, rin),
                          [&](int k) { alive_[static_cast<std::size_t>(k)] = 0; });
  }

  const std::vector<Eigen::Vector3f>& points_;
  const std::vector<Eigen::Vector3f>& normals_;
  const SphereRansacParams& P_;
  const bool use_normals_;
  SphereSegmentation& out_;
  Indices alive_list_;
  std::vector<std::uint8_t> alive_;
  std::vector<Eigen::Vector3d> eyes_;
  const double thr_, cos_tol_, r_lo_, r_hi_, reach_;
  const detail::VoxelGrid grid_;
  common::SplitMixRandom rng_;
  const int k_points_;
};

}  // namespace

SphereSegmentation segment_spheres(const std::vector<Eigen::Vector3f>& points,
                                   const std::vector<Eigen::Vector3f>& normals, const SphereRansacParams& P,
                                   const std::vector<Eigen::Vector3f>& viewpoints) {
  SphereSegmentation out;
  if (viewpoints.empty()) {
    out.status = common::Status::invalid("no viewpoint");
    return out;
  }
  if (const common::Status why = validate(P); !why.ok()) {
    out.status = common::Status::invalid("bad sphere parameters: " + why.message);
    return out;
  }
  const bool use_normals = P.normal_tolerance_deg > 0 || P.hypothesis == SphereHypothesis::kTwoPointsWithNormals;
  if (use_normals && normals.size() != points.size()) {
    out.status =
        common::Status::invalid("normals are needed (" + std::string(to_string(P.hypothesis)) + ", normal tolerance " +
                                std::to_string(P.normal_tolerance_deg) + " deg) but " + std::to_string(normals.size()) +
                                " normals came with " + std::to_string(points.size()) + " points");
    return out;
  }
  Indices alive_list;
  for (std::size_t k = 0; k < points.size(); ++k)
    if (points[k].allFinite() && (!use_normals || normals[k].allFinite())) alive_list.push_back(static_cast<int>(k));
  if (static_cast<int>(alive_list.size()) < P.min_remaining) {
    out.remaining_points = static_cast<int>(alive_list.size());
    out.status =
        common::Status::not_found(points.empty() ? "no points"
                                                 : "only " + std::to_string(alive_list.size()) + " usable points (< " +
                                                       std::to_string(P.min_remaining) + ")");
    return out;
  }
  SphereSegmenter(points, normals, P, viewpoints, use_normals, std::move(alive_list), out).run();
  return out;
}

common::Status validate(const NoiseBiasParams& p) { return common::within_table(p); }

namespace {
// The upper median (the element nth_element puts in the middle).
double median_of(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The range along the ray from `eye` through `p` to the sphere's front, and
// the cosine of the ray's incidence there; nullopt when the ray misses.
std::optional<std::pair<double, double>> front_along_ray(const Eigen::Vector3d& eye, const Eigen::Vector3d& u,
                                                         const Sphere& s) {
  const Eigen::Vector3d ec = s.centre - eye;
  const double b = u.dot(ec);
  const double disc = b * b - (ec.squaredNorm() - s.radius_m * s.radius_m);
  if (!(disc > 0) || b <= 0) return std::nullopt;
  const double t = b - std::sqrt(disc);
  const Eigen::Vector3d n = (eye + t * u - s.centre) / s.radius_m;
  return std::make_pair(t, -n.dot(u));
}
}  // namespace

DepthNoise measure_depth_noise(const std::vector<Eigen::Vector3f>& points, const std::vector<std::uint8_t>& view_of,
                               const std::vector<Eigen::Vector3f>& viewpoints, const Sphere& sphere,
                               const NoiseBiasParams& P) {
  DepthNoise out;
  if (view_of.size() != points.size() || !(sphere.radius_m > 0)) return out;
  const double reach2 = std::pow(sphere.radius_m + P.band_m, 2);
  std::vector<std::vector<double>> by_view(viewpoints.size());
  Eigen::Vector3d away = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d p = points[k].cast<double>();
    if (view_of[k] >= viewpoints.size() || (p - sphere.centre).squaredNorm() > reach2) continue;
    const Eigen::Vector3d eye = viewpoints[view_of[k]].cast<double>();
    const double range = (p - eye).norm();
    const auto front = front_along_ray(eye, (p - eye) / range, sphere);
    if (!front || front->second < P.min_cos || std::abs(range - front->first) > P.band_m) continue;
    by_view[view_of[k]].push_back(range - front->first);
    away += (sphere.centre - eye).normalized();
  }
  // Robust spread about each view's own median (a view's pose error shifts
  // all its points alike; occluders in front are outliers).
  std::vector<double> residuals;
  for (const auto& v : by_view) {
    if (v.empty()) continue;
    const double med = median_of(v);
    for (double x : v) residuals.push_back(std::abs(x - med));
  }
  if (static_cast<int>(residuals.size()) < P.min_points) return out;
  out.sigma_m = 1.4826 * median_of(residuals);
  out.points = static_cast<int>(residuals.size());
  out.away = away.normalized();
  return out;
}

Sphere correct_noise_bias(const Sphere& sphere, const DepthNoise& noise, const NoiseBiasParams& P, double r_min,
                          double r_max) {
  if (!P.enabled || noise.points == 0) return sphere;
  const double var = noise.sigma_m * noise.sigma_m;
  Sphere out = sphere;
  out.radius_m = std::clamp(sphere.radius_m + P.radius_bias_m + P.radius_per_var * var, r_min, r_max);
  out.centre += (P.centre_bias_m + P.centre_per_var * var) * noise.away;
  return out;
}

}  // namespace tinyline::tomato_reasoning
