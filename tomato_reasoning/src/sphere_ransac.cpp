#include "tomato_reasoning/sphere_ransac.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Dense>

#include "voxel_hash.hpp"

#include <tinyline/common/least_squares.hpp>
#include <tinyline/common/random.hpp>

namespace tinyline::tomato_reasoning {

std::optional<Sphere> sphere_from_four_points(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                              const Eigen::Vector3d& d) {
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

  Sphere sphere(const Eigen::VectorXd& x) const {
    return {x.head<3>(), fix_radius ? radius_m : x[3]};
  }
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

SphereRefinement refine_sphere(const std::vector<Eigen::Vector3f>& points, const Indices& indices, const Sphere& initial,
                               double r_min, double r_max) {
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

common::Validation validate(const SphereRansacParams& p) {
  if (!(p.radius_min_m > 0) || !(p.radius_max_m >= p.radius_min_m) || !std::isfinite(p.radius_max_m))
    return common::Validation::invalid("radius range must satisfy 0 < radius_min_m <= radius_max_m (finite)");
  if (!(p.inlier_distance_m > 0) || !std::isfinite(p.inlier_distance_m)) return common::Validation::invalid("inlier_distance_m must be finite and > 0");
  if (!(p.normal_tolerance_deg < 90) || std::isnan(p.normal_tolerance_deg)) return common::Validation::invalid("normal_tolerance_deg must be < 90 (<= 0: off)");
  if (p.max_iterations < 1) return common::Validation::invalid("max_iterations must be >= 1");
  if (!(p.confidence > 0 && p.confidence < 1)) return common::Validation::invalid("confidence must be in (0, 1)");
  if (p.min_inliers < 4) return common::Validation::invalid("min_inliers must be >= 4 (a sphere has four parameters)");
  if (p.min_remaining < 4) return common::Validation::invalid("min_remaining must be >= 4");
  if (p.max_spheres < 1) return common::Validation::invalid("max_spheres must be >= 1");
  if (p.max_failed_rounds < 1) return common::Validation::invalid("max_failed_rounds must be >= 1");
  if (!(p.max_overlap_m >= 0)) return common::Validation::invalid("max_overlap_m must be >= 0");
  if (!(p.removal_factor >= 1)) return common::Validation::invalid("removal_factor must be >= 1");
  return common::Validation::ok();
}

SphereSegmentation segment_spheres(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                   const SphereRansacParams& P, const Eigen::Vector3f& viewpoint) {
  return segment_spheres(points, normals, P, std::vector<Eigen::Vector3f>{viewpoint});
}

SphereSegmentation segment_spheres(const std::vector<Eigen::Vector3f>& points, const std::vector<Eigen::Vector3f>& normals,
                                   const SphereRansacParams& P, const std::vector<Eigen::Vector3f>& viewpoints) {
  SphereSegmentation out;
  if (viewpoints.empty()) {
    out.stop_reason = "no viewpoint";
    return out;
  }
  if (const common::Validation why = validate(P); !why.valid) {
    out.stop_reason = "bad sphere parameters: " + why.reason;
    return out;
  }
  const bool use_normals = P.normal_tolerance_deg > 0 || P.hypothesis == SphereHypothesis::kTwoPointsWithNormals;
  if (use_normals && normals.size() != points.size()) {
    out.stop_reason = "normals are needed (" + std::string(to_string(P.hypothesis)) + ", normal tolerance " +
                      std::to_string(P.normal_tolerance_deg) + " deg) but " + std::to_string(normals.size()) +
                      " normals came with " + std::to_string(points.size()) + " points";
    return out;
  }
  Indices alive_list;
  for (std::size_t k = 0; k < points.size(); ++k)
    if (points[k].allFinite() && (!use_normals || normals[k].allFinite())) alive_list.push_back(static_cast<int>(k));
  if (static_cast<int>(alive_list.size()) < P.min_remaining) {
    out.remaining_points = static_cast<int>(alive_list.size());
    out.stop_reason = points.empty() ? "no points" : "only " + std::to_string(alive_list.size()) + " usable points (< " +
                                                         std::to_string(P.min_remaining) + ")";
    return out;
  }
  std::vector<std::uint8_t> alive(points.size(), 0);
  for (int k : alive_list) alive[static_cast<std::size_t>(k)] = 1;

  const double thr = P.inlier_distance_m;
  const double cos_tol = P.normal_tolerance_deg > 0 ? std::cos(P.normal_tolerance_deg * M_PI / 180.0) : -2.0;
  const double r_lo = P.radius_min_m - thr, r_hi = P.radius_max_m + thr;
  const double reach = 2.0 * P.radius_max_m;  // a hypothesis's points lie within one diameter
  std::vector<Eigen::Vector3d> eyes;
  for (const auto& v : viewpoints) eyes.push_back(v.cast<double>());
  // Largest cosine between (q - c) and (eye - c) over the viewpoints: > 0 when
  // some camera sees the side of the sphere that q lies on.
  auto facing = [&](const Eigen::Vector3d& q, const Eigen::Vector3d& c) {
    double best = -2;
    const Eigen::Vector3d a = (q - c).normalized();
    for (const auto& e : eyes) best = std::max(best, a.dot((e - c).normalized()));
    return best;
  };
  // Scoring looks only at cells that the sphere's shell can reach.
  const double score_cell = std::max(0.01, P.radius_max_m / 2.0);
  const detail::VoxelGrid grid(points, alive_list, score_cell);
  common::SplitMixRandom rng(common::stream_seed(P.seed, 0x632be59bd9b4e019ULL));
  const int k_points = P.hypothesis == SphereHypothesis::kFourPoints ? 4 : 2;

  struct Scored {
    Sphere s;
    int count = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  };
  // Inliers of sphere s among the alive points (optionally listing them).
  auto score = [&](const Sphere& s, double dist_thr, Indices* list) {
    Scored r;
    r.s = s;
    const float lim = static_cast<float>(s.radius_m + dist_thr);
    const Eigen::Vector3f c = s.centre.cast<float>();
    const detail::CellKey lo = grid.key_of(c - Eigen::Vector3f::Constant(lim));
    const detail::CellKey hi = grid.key_of(c + Eigen::Vector3f::Constant(lim));
    for (int x = lo.x; x <= hi.x; ++x)
      for (int y = lo.y; y <= hi.y; ++y)
        for (int z = lo.z; z <= hi.z; ++z) {
          const int cell = grid.find({x, y, z});
          if (cell < 0) continue;
          for (const int* m = grid.begin(std::size_t(cell)); m != grid.end(std::size_t(cell)); ++m) {
            const std::size_t k = static_cast<std::size_t>(*m);
            if (!alive[k]) continue;
            const Eigen::Vector3d d = points[k].cast<double>() - s.centre;
            const double dist = d.norm();
            if (std::abs(dist - s.radius_m) > dist_thr || dist < 1e-9) continue;
            if (use_normals && cos_tol > -1.5 && normals[k].cast<double>().dot(d) < cos_tol * dist) continue;
            ++r.count;
            r.sum += points[k].cast<double>();
            if (list) list->push_back(*m);
          }
        }
    return r;
  };
  // Would this sphere be acceptable as a tomato here?
  auto plausible = [&](const Scored& r, bool count_rejections) {
    if (r.count == 0) return false;
    const Eigen::Vector3d centroid = r.sum / r.count;
    if (facing(centroid, r.s.centre) <= 0) {  // the visible cap faces away from every camera
      if (count_rejections) ++out.rejected_cap;
      return false;
    }
    for (const auto& f : out.spheres) {
      if ((f.sphere.centre - r.s.centre).norm() < f.sphere.radius_m + r.s.radius_m - P.max_overlap_m) {
        if (count_rejections) ++out.rejected_overlap;
        return false;
      }
    }
    return true;
  };

  int failed = 0;
  std::vector<int> pool;
  while (true) {
    alive_list.erase(std::remove_if(alive_list.begin(), alive_list.end(), [&](int k) { return !alive[static_cast<std::size_t>(k)]; }),
                     alive_list.end());
    out.remaining_points = static_cast<int>(alive_list.size());
    if (out.remaining_points < P.min_remaining) {
      out.stop_reason = std::to_string(out.remaining_points) + " points remain (< " + std::to_string(P.min_remaining) + ")";
      break;
    }
    if (static_cast<int>(out.spheres.size()) >= P.max_spheres) {
      out.stop_reason = "max_spheres (" + std::to_string(P.max_spheres) + ") reached";
      break;
    }
    ++out.rounds;
    Scored best;
    double local_share = 0.5;  // inlier share near a model's first point, for Eq. 4.15
    long needed = P.max_iterations;
    const std::size_t n_alive = alive_list.size();
    for (long it = 0; it < needed; ++it) {
      ++out.hypotheses;
      const int first = alive_list[rng.index(n_alive)];
      const Eigen::Vector3d p0 = points[static_cast<std::size_t>(first)].cast<double>();
      // The other points: near the first (rejection sampling, a few tries), or anywhere.
      int sample[4] = {first, -1, -1, -1};
      bool ok = true;
      for (int j = 1; j < k_points && ok; ++j) {
        ok = false;
        for (int tries = 0; tries < 64; ++tries) {
          const int cand = alive_list[rng.index(n_alive)];
          if (cand == first || cand == sample[1] || cand == sample[2]) continue;
          if (P.local_sampling && (points[static_cast<std::size_t>(cand)].cast<double>() - p0).norm() > reach) continue;
          sample[j] = cand;
          ok = true;
          break;
        }
      }
      std::optional<Sphere> s;
      if (ok) {
        auto pt = [&](int j) { return points[static_cast<std::size_t>(sample[j])].cast<double>(); };
        if (k_points == 4) {
          s = sphere_from_four_points(pt(0), pt(1), pt(2), pt(3));
        } else {
          const Eigen::Vector3d n0 = normals[static_cast<std::size_t>(sample[0])].cast<double>();
          const Eigen::Vector3d n1 = normals[static_cast<std::size_t>(sample[1])].cast<double>();
          s = sphere_from_two_points_with_normals(pt(0), n0, pt(1), n1);
          // Normals face the camera, so the centre must lie behind both points.
          if (s && ((pt(0) - s->centre).dot(n0) <= 0 || (pt(1) - s->centre).dot(n1) <= 0)) s.reset();
          if (s && std::abs((pt(0) - s->centre).norm() - (pt(1) - s->centre).norm()) > 2 * thr) s.reset();
        }
      }
      if (!s || s->radius_m < r_lo || s->radius_m > r_hi) {
        ++out.degenerate;
        continue;
      }
      // The first point must lie on a visible half.
      if (facing(p0, s->centre) <= 0) {
        ++out.degenerate;
        continue;
      }
      const Scored r = score(*s, thr, nullptr);
      if (r.count <= best.count || !plausible(r, false)) continue;
      best = r;
      // Eq. 4.13-4.15: samples needed for `confidence`, the first point drawn
      // from all alive points, the others (locally) from the model's neighbourhood.
      if (P.local_sampling) {
        int near = 0;
        grid.for_each_within(points, best.s.centre.cast<float>(), static_cast<float>(best.s.radius_m + reach),
                             [&](int k) { near += alive[static_cast<std::size_t>(k)]; });
        local_share = std::min(1.0, best.count / std::max(1.0, double(near)));
      } else {
        local_share = best.count / double(n_alive);
      }
      const double w = (best.count / double(n_alive)) * std::pow(local_share, k_points - 1);
      if (w >= 1.0) {
        needed = it + 1;
      } else if (w > 0) {
        needed = std::min<long>(P.max_iterations,
                                static_cast<long>(std::ceil(std::log(1.0 - P.confidence) / std::log(1.0 - w))));
      }
    }
    if (best.count < P.min_inliers) {
      if (++failed >= P.max_failed_rounds) {
        out.stop_reason = std::to_string(failed) + " round(s) without a model of >= " + std::to_string(P.min_inliers) +
                          " inliers (" + std::to_string(out.remaining_points) + " points left)";
        break;
      }
      continue;
    }
    // Refine on the inliers, then take the refined model's inliers.
    Indices inliers;
    (void)score(best.s, thr, &inliers);
    Sphere model = best.s;
    bool at_limit = false;
    double rms = 0;
    if (P.refine) {
      const SphereRefinement ref = refine_sphere(points, inliers, best.s, P.radius_min_m, P.radius_max_m);
      if (ref.sphere.centre.allFinite()) {
        model = ref.sphere;
        at_limit = ref.radius_at_limit;
      }
    }
    Indices final_inliers;
    const Scored fin = score(model, thr, &final_inliers);
    if (fin.count < P.min_inliers || !plausible(fin, true)) {
      // Refinement moved it somewhere unacceptable: drop its points from
      // sampling this round's way (keep them for others) by failing the round.
      if (++failed >= P.max_failed_rounds) {
        out.stop_reason = "the best models were refused (cap facing away or overlap) " + std::to_string(failed) + " times";
        break;
      }
      continue;
    }
    failed = 0;
    for (int k : final_inliers) {
      const double e = (points[static_cast<std::size_t>(k)].cast<double>() - model.centre).norm() - model.radius_m;
      rms += e * e;
    }
    SphereFit fit;
    fit.sphere = model;
    fit.inliers = final_inliers;
    fit.rms_m = std::sqrt(rms / std::max<std::size_t>(1, final_inliers.size()));
    fit.radius_at_limit = at_limit;
    fit.cap_facing = facing(fin.sum / fin.count, model.centre);
    fit.round = out.rounds;
    // Remove the fruit's points: its shell (a little wider than the inlier
    // band, normals agreeing) and anything inside it.
    Indices removed;
    (void)score(model, P.removal_factor * thr, &removed);
    for (int k : removed) alive[static_cast<std::size_t>(k)] = 0;
    const float rin = static_cast<float>(model.radius_m - thr);
    grid.for_each_within(points, model.centre.cast<float>(), std::max(0.0f, rin), [&](int k) { alive[static_cast<std::size_t>(k)] = 0; });
    out.spheres.push_back(std::move(fit));
  }
  return out;
}

}  // namespace tinyline::tomato_reasoning
