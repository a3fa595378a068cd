// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/scoring.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>
#include <sstream>

#include <Eigen/Geometry>

namespace tinyline::tomato_reasoning::eval {

namespace {
double deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}
// Distance [m] from p to the true pedicel's path (anchor to calyx), reference frame.
double distance_to_pedicel(const Scenario& s, std::size_t t, const Eigen::Vector3d& p) {
  if (t >= s.truss.tomatoes.size()) return NAN;
  const auto& tt = s.truss.tomatoes[t];
  std::vector<Eigen::Vector3d> path = tt.pedicel_path_m;
  if (path.size() < 2) path = {tt.anchor_m, tt.calyx_m};
  const Eigen::Isometry3d T_ref_world = s.frame().T_world_camera.inverse();
  double best = INFINITY;
  for (std::size_t k = 0; k + 1 < path.size(); ++k) {
    const Eigen::Vector3d a = T_ref_world * path[k], b = T_ref_world * path[k + 1];
    const double u = std::clamp((p - a).dot(b - a) / std::max(1e-12, (b - a).squaredNorm()), 0.0, 1.0);
    best = std::min(best, (a + u * (b - a) - p).norm());
  }
  return best;
}
// The errors of detection `d` of true tomato `t`.
void score_detection(const Scenario& s, std::size_t t, const Tomato& d, const ScoreParams& p, TomatoScore& ts) {
  const TruthTomato& tr = s.truth[t];
  ts.centre_error_m = (d.fit.sphere.centre - tr.centre_m).norm();
  ts.radius_error_m = d.fit.sphere.radius_m - tr.radius_m;
  ts.centre_toward_camera_m = -(d.fit.sphere.centre - tr.centre_m).dot(tr.centre_m.normalized());
  ts.depth_noise_m = d.fit.depth_noise_m;
  ts.uncorrected_radius_error_m = d.fit.uncorrected.radius_m - tr.radius_m;
  ts.uncorrected_toward_camera_m = -(d.fit.uncorrected.centre - tr.centre_m).dot(tr.centre_m.normalized());
  ts.edges_estimated = d.pedicel.edges;
  ts.pedicel_error_deg = deg(d.pedicel.expected_dir, tr.pedicel_dir);
  ts.prior_pedicel_error_deg = deg(d.pedicel_prior.expected_dir, tr.pedicel_dir);
  ts.pedicel_seen = d.sighting.seen;
  ts.seen_points = d.sighting.points;
  if (d.sighting.seen) ts.seen_error_deg = deg(d.sighting.direction, tr.pedicel_dir);
  ts.cut_point_axis_mm = 1000 * distance_to_pedicel(s, t, d.cut.point);
  if (tr.pedicel_force_n.norm() > 1e-9) ts.force_dir_error_deg = deg(d.pedicel.expected_dir, tr.pedicel_force_n);
  ts.truth_in_hpd = d.pedicel.distribution.in_hpd(tr.pedicel_dir, p.hpd_mass);
  ts.spread50_deg = d.pedicel.spread50_deg;
  ts.cut_coverage = d.cut.coverage;
  ts.cut_covers_truth = std::cos(d.cut.half_angle_rad) <= d.cut.direction.dot(tr.pedicel_dir.normalized());
  ts.pick_rank = d.pick_rank;
}
}  // namespace

double percentile(std::vector<double> v, double pct) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return std::isnan(x); }), v.end());
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double pos = pct / 100.0 * static_cast<double>(v.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(v.size() - 1, lo + 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

TrussScore score_truss(const Scenario& s, const PipelineResult& r, const ScoreParams& p) {
  TrussScore out;
  out.complexity = static_cast<char>(s.complexity);
  out.seed = s.seed;
  out.ok = r.status.ok();
  out.stage = std::string(to_string(r.stage));
  out.reason = r.status.message;
  out.times = r.times;
  out.truth = static_cast<int>(s.truth.size());
  out.detections = static_cast<int>(r.tomatoes.size());
  const auto& K = s.frame().intrinsics;

  // Greedy matching by distance: true tomatoes are >= 5 cm apart, so a
  // sphere within 1 cm of one cannot be within 1 cm of another.
  struct Pair {
    double d;
    int t, k;
  };
  std::vector<Pair> pairs;
  for (std::size_t t = 0; t < s.truth.size(); ++t)
    for (std::size_t k = 0; k < r.tomatoes.size(); ++k)
      pairs.push_back({(r.tomatoes[k].fit.sphere.centre - s.truth[t].centre_m).norm(), int(t), int(k)});
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d < b.d; });
  std::vector<int> det_of(s.truth.size(), -1), truth_of(r.tomatoes.size(), -1);
  for (const auto& pr : pairs) {
    if (pr.d > p.match_distance_m) break;
    if (det_of[std::size_t(pr.t)] >= 0 || truth_of[std::size_t(pr.k)] >= 0) continue;
    det_of[std::size_t(pr.t)] = pr.k;
    truth_of[std::size_t(pr.k)] = pr.t;
  }

  for (std::size_t t = 0; t < s.truth.size(); ++t) {
    const TruthTomato& tr = s.truth[t];
    TomatoScore ts;
    ts.truth = int(t);
    const double z = tr.centre_m.z();
    const double disc_px =
        z > tr.radius_m ? M_PI * std::pow(K.fx * tr.radius_m / std::sqrt(z * z - tr.radius_m * tr.radius_m), 2) : 0;
    // The best view's share (equal distances: the orbit keeps the range).
    ts.visible_share = disc_px > 0 ? std::min(1.0, tr.visible_pixels_any / disc_px) : 0.0;
    ts.edges_true = tr.edges;
    ts.gravity_only_error_deg = deg(-s.gravity_camera, tr.pedicel_dir);
    const bool visible = ts.visible_share >= p.visible_share;
    out.visible += visible;
    const int k = det_of[t];
    if (k >= 0) {
      ts.detection = k;
      ++out.detected;
      out.visible_detected += visible;
      score_detection(s, t, r.tomatoes[std::size_t(k)], p, ts);
    }
    out.tomatoes.push_back(ts);
  }
  for (std::size_t k = 0; k < r.tomatoes.size(); ++k) {
    if (truth_of[k] >= 0) continue;
    ++out.unmatched;
    for (const auto& c : s.distractors) {
      if ((r.tomatoes[k].fit.sphere.centre - c).norm() < 0.03) {
        ++out.on_distractor;
        break;
      }
    }
  }
  // Contact graph among detected tomatoes.
  std::set<std::pair<int, int>> truth_edges;
  for (const auto& [i, j] : s.contacts) truth_edges.insert({std::min(i, j), std::max(i, j)});
  std::set<std::pair<int, int>> est_edges;
  for (const auto& e : r.edges) {
    const int a = truth_of[std::size_t(e.i)], b = truth_of[std::size_t(e.j)];
    if (a < 0 || b < 0) continue;  // edges to spurious spheres are not scored
    est_edges.insert({std::min(a, b), std::max(a, b)});
  }
  for (const auto& e : est_edges) (truth_edges.count(e) ? out.edges_tp : out.edges_fp)++;
  for (const auto& e : truth_edges)
    if (det_of[std::size_t(e.first)] >= 0 && det_of[std::size_t(e.second)] >= 0 && !est_edges.count(e)) ++out.edges_fn;
  out.first_pick_real = !r.pick_order.empty() && truth_of[std::size_t(r.pick_order.front())] >= 0;
  return out;
}

std::vector<int> pick_order_in_truth(const Scenario& s, const PipelineResult& r, const ScoreParams& p) {
  std::vector<int> out;
  for (int k : r.pick_order) {
    int best = -1;
    double d = p.match_distance_m;
    for (std::size_t t = 0; t < s.truth.size(); ++t) {
      const double e = (r.tomatoes[std::size_t(k)].fit.sphere.centre - s.truth[t].centre_m).norm();
      if (e < d) d = e, best = int(t);
    }
    out.push_back(best);
  }
  return out;
}

Summary summarize(const std::vector<TrussScore>& scores) {
  Summary s;
  std::vector<double> ce, re, pe, ge, ms, prior, seen_prior, seen_post, rb, tc;
  int hpd = 0, hpd_n = 0, cover = 0;
  double cov_sum = 0;
  int tp = 0, fp = 0, fn = 0;
  for (const auto& t : scores) {
    ++s.trusses;
    s.truth += t.truth;
    s.detected += t.detected;
    s.visible += t.visible;
    s.visible_detected += t.visible_detected;
    s.detections += t.detections;
    s.unmatched += t.unmatched;
    tp += t.edges_tp;
    fp += t.edges_fp;
    fn += t.edges_fn;
    if (t.ok) ms.push_back(t.times.total_ms());
    for (const auto& x : t.tomatoes) {
      ge.push_back(x.gravity_only_error_deg);
      if (x.detection < 0) continue;
      ce.push_back(1000 * x.centre_error_m);
      re.push_back(1000 * std::abs(x.radius_error_m));
      pe.push_back(x.pedicel_error_deg);
      prior.push_back(x.prior_pedicel_error_deg);
      rb.push_back(1000 * x.radius_error_m);
      tc.push_back(1000 * x.centre_toward_camera_m);
      if (x.pedicel_seen) {
        ++s.seen;
        seen_prior.push_back(x.prior_pedicel_error_deg);
        seen_post.push_back(x.pedicel_error_deg);
      }
      hpd += x.truth_in_hpd;
      cover += x.cut_covers_truth;
      cov_sum += x.cut_coverage;
      ++hpd_n;
    }
  }
  s.centre_median_mm = percentile(ce, 50);
  s.centre_p95_mm = percentile(ce, 95);
  s.radius_median_mm = percentile(re, 50);
  s.radius_p95_mm = percentile(re, 95);
  s.pedicel_median_deg = percentile(pe, 50);
  s.pedicel_p95_deg = percentile(pe, 95);
  s.prior_pedicel_median_deg = percentile(prior, 50);
  s.radius_bias_mm = percentile(rb, 50);
  s.centre_toward_camera_mm = percentile(tc, 50);
  s.seen_prior_median_deg = percentile(seen_prior, 50);
  s.seen_posterior_median_deg = percentile(seen_post, 50);
  s.gravity_only_median_deg = percentile(ge, 50);
  s.gravity_only_p95_deg = percentile(ge, 95);
  if (hpd_n > 0) {
    s.hpd_hit_rate = double(hpd) / hpd_n;
    s.cut_cover_rate = double(cover) / hpd_n;
    s.mean_cut_coverage = cov_sum / hpd_n;
  }
  if (tp + fp > 0) s.edge_precision = double(tp) / (tp + fp);
  if (tp + fn > 0) s.edge_recall = double(tp) / (tp + fn);
  s.total_ms_median = percentile(ms, 50);
  s.total_ms_p95 = percentile(ms, 95);
  return s;
}

std::string csv_header() {
  return "class,seed,truth,detection,visible_share,centre_error_mm,radius_error_mm,edges_true,edges_estimated,"
         "pedicel_error_deg,gravity_only_error_deg,force_dir_error_deg,truth_in_hpd50,spread50_deg,cut_coverage,"
         "cut_covers_truth,pick_rank,prior_pedicel_error_deg,pedicel_seen,seen_points,seen_error_deg,cut_point_axis_"
         "mm,depth_noise_mm,toward_camera_mm,uncorrected_radius_error_mm,uncorrected_toward_camera_mm\n";
}

std::string csv_rows(const TrussScore& s) {
  std::ostringstream o;
  o.precision(6);
  for (const auto& t : s.tomatoes) {
    o << s.complexity << ',' << s.seed << ',' << t.truth << ',' << t.detection << ',' << t.visible_share << ','
      << 1000 * t.centre_error_m << ',' << 1000 * t.radius_error_m << ',' << t.edges_true << ',' << t.edges_estimated
      << ',' << t.pedicel_error_deg << ',' << t.gravity_only_error_deg << ',' << t.force_dir_error_deg << ','
      << int(t.truth_in_hpd) << ',' << t.spread50_deg << ',' << t.cut_coverage << ',' << int(t.cut_covers_truth) << ','
      << t.pick_rank << ',' << t.prior_pedicel_error_deg << ',' << int(t.pedicel_seen) << ',' << t.seen_points << ','
      << t.seen_error_deg << ',' << t.cut_point_axis_mm << ',' << 1000 * t.depth_noise_m << ','
      << 1000 * t.centre_toward_camera_m << ',' << 1000 * t.uncorrected_radius_error_m << ','
      << 1000 * t.uncorrected_toward_camera_m << '\n';
  }
  return o.str();
}

std::string to_json(const Summary& s) {
  std::ostringstream o;
  o.precision(6);
  auto num = [&](const char* k, double v, bool last = false) {
    o << "  \"" << k << "\": ";
    if (std::isnan(v))
      o << "null";
    else
      o << v;
    o << (last ? "\n" : ",\n");
  };
  o << "{\n";
  num("trusses", s.trusses);
  num("truth", s.truth);
  num("detected", s.detected);
  num("detection_rate", s.truth ? double(s.detected) / s.truth : NAN);
  num("visible", s.visible);
  num("visible_detected", s.visible_detected);
  num("visible_detection_rate", s.visible ? double(s.visible_detected) / s.visible : NAN);
  num("detections", s.detections);
  num("unmatched", s.unmatched);
  num("centre_median_mm", s.centre_median_mm);
  num("centre_p95_mm", s.centre_p95_mm);
  num("radius_median_mm", s.radius_median_mm);
  num("radius_p95_mm", s.radius_p95_mm);
  num("pedicel_median_deg", s.pedicel_median_deg);
  num("pedicel_p95_deg", s.pedicel_p95_deg);
  num("prior_pedicel_median_deg", s.prior_pedicel_median_deg);
  num("pedicel_seen", s.seen);
  num("seen_prior_median_deg", s.seen_prior_median_deg);
  num("seen_posterior_median_deg", s.seen_posterior_median_deg);
  num("gravity_only_median_deg", s.gravity_only_median_deg);
  num("gravity_only_p95_deg", s.gravity_only_p95_deg);
  num("hpd50_hit_rate", s.hpd_hit_rate);
  num("cut_cover_rate", s.cut_cover_rate);
  num("mean_cut_coverage", s.mean_cut_coverage);
  num("edge_precision", s.edge_precision);
  num("edge_recall", s.edge_recall);
  num("total_ms_median", s.total_ms_median);
  num("total_ms_p95", s.total_ms_p95, true);
  o << "}\n";
  return o.str();
}

std::string without_figures(const std::string& reason) {
  std::string out;
  bool in_number = false;  // a decimal point inside a number belongs to it
  for (const char c : reason.substr(0, reason.find('('))) {
    const bool digit = std::isdigit(static_cast<unsigned char>(c)) != 0;
    if (digit && !in_number) out += 'N';
    if (!digit && !(in_number && c == '.')) out += c;
    in_number = digit || (in_number && c == '.');
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ':')) out.pop_back();
  return out;
}

}  // namespace tinyline::tomato_reasoning::eval
