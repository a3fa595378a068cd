// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/pipeline.hpp"

#include "tomato_reasoning/param_tables.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace tinyline::tomato_reasoning {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// HSI filter per view, red points into the reference frame; the first empty
// view's reason.
std::string filter_views(const std::vector<View>& views, const HsiFilterParams& params, PipelineResult& r) {
  std::string hsi_reason;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const HsiFilterResult hsi = filter_hsi(views[v].cloud, params);
    r.finite_points += hsi.finite;
    if (hsi.indices.empty() && hsi_reason.empty()) hsi_reason = hsi.status.message;
    const Eigen::Isometry3f T = views[v].T_ref_camera.cast<float>();
    for (int k : hsi.indices) {
      r.red_xyz.push_back(T * views[v].cloud.point(static_cast<std::size_t>(k)));
      r.red_view.push_back(static_cast<std::uint8_t>(v));
    }
    r.viewpoints.push_back(T.translation());
  }
  return hsi_reason;
}

// The green points of every view within reach of a found fruit's pedicel
// (the spheres' box grown by the largest radius and the evidence's shell).
GreenPoints gather_green(const std::vector<View>& views, const std::vector<SphereFit>& fits,
                         const std::vector<Eigen::Vector3f>& viewpoints, const PedicelEvidenceParams& P) {
  GreenPoints g;
  g.viewpoints = viewpoints;
  Eigen::AlignedBox3f box;
  for (const auto& f : fits) {
    const float reach = static_cast<float>(f.sphere.radius_m + P.shell_outer_m);
    const Eigen::Vector3f c = f.sphere.centre.cast<float>();
    box.extend(c - Eigen::Vector3f::Constant(reach));
    box.extend(c + Eigen::Vector3f::Constant(reach));
  }
  for (std::size_t v = 0; v < views.size(); ++v) {
    const CloudView& cloud = views[v].cloud;
    const Eigen::Isometry3f T = views[v].T_ref_camera.cast<float>();
    for (std::size_t k = 0; k < cloud.size(); ++k) {
      if (!is_green(cloud.colour(k), P)) continue;
      const Eigen::Vector3f p = cloud.point(k);
      if (!p.allFinite()) continue;
      const Eigen::Vector3f q = T * p;
      if (!box.contains(q)) continue;
      g.xyz.push_back(q);
      g.view.push_back(static_cast<std::uint8_t>(v));
    }
  }
  return g;
}

// Each sphere's depth noise measured on the raw points and its bias removed.
void correct_spheres(const PipelineResult& r, const PipelineParams& P, std::vector<SphereFit>& fits) {
  for (SphereFit& f : fits) {
    f.uncorrected = f.sphere;
    const DepthNoise noise = measure_depth_noise(r.red_xyz, r.red_view, r.viewpoints, f.sphere, P.noise_bias);
    f.depth_noise_m = noise.sigma_m;
    f.sphere = correct_noise_bias(f.sphere, noise, P.noise_bias, P.spheres.radius_min_m, P.spheres.radius_max_m);
  }
}

// The cut on the seen pedicel when the plan cuts along it.
void cut_on_seen_pedicel(const Sphere& s, const PedicelSighting& seen, double cone_deg, CutPlan& cut) {
  if (!seen.cut_point_seen) return;
  const Eigen::Vector3d d = (seen.cut_point - s.centre).normalized();
  if (d.dot(cut.direction) < std::cos(cone_deg * M_PI / 180.0)) return;
  cut.point = seen.cut_point;
  cut.direction = d;
}
}  // namespace

common::Status validate(const PipelineParams& p) {
  for (const common::Status& v : std::initializer_list<common::Status>{
           validate(p.hsi).within("hsi"), validate(p.branch).within("branch"),
           validate(p.smoothing).within("smoothing"), validate(p.spheres).within("spheres"),
           validate(p.noise_bias).within("noise_bias"), validate(p.force).within("force"),
           validate(p.pedicel).within("pedicel")}) {
    if (!v.ok()) return v;
  }
  if (!p.gravity.allFinite() || !(p.gravity.norm() > 1e-9))
    return common::Status::invalid("gravity must be a finite, non-zero vector");
  if (common::Status s = common::within_table(p.cut); !s.ok()) return s.within("cut");
  return common::Status{};
}

TomatoPipeline::TomatoPipeline(PipelineParams params) : params_(std::move(params)) {
  if (const common::Status why = validate(params_); !why.ok())
    throw std::invalid_argument("tomato pipeline: " + why.message);
}

PipelineResult TomatoPipeline::run(const CloudView& cloud) const {
  View v;
  v.cloud = cloud;
  return run(std::vector<View>{v});
}

std::string_view to_string(PipelineStage stage) {
  switch (stage) {
    case PipelineStage::kNone: return "";
    case PipelineStage::kInput: return "input";
    case PipelineStage::kHsi: return "hsi";
    case PipelineStage::kBranch: return "branch";
    case PipelineStage::kSmoothing: return "smoothing";
    case PipelineStage::kSpheres: return "spheres";
  }
  return "";
}

namespace {
/// `r` stopped at `stage` for `why`: bad input there, or nothing found.
PipelineResult& stopped(PipelineResult& r, PipelineStage stage, std::string why) {
  r.stage = stage;
  r.status = {stage == PipelineStage::kInput ? common::StatusCode::InvalidArgument : common::StatusCode::NotFound,
              std::move(why)};
  return r;
}
}  // namespace

PipelineResult TomatoPipeline::run(const std::vector<View>& views) const {
  PipelineResult r;
  auto stop = [&](PipelineStage stage, std::string why) { return stopped(r, stage, std::move(why)); };
  using enum PipelineStage;
  if (views.empty()) return stop(kInput, "no views");
  if (views.size() > 255) return stop(kInput, "more than 255 views");
  std::size_t total = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const std::string name = views.size() > 1 ? "view " + std::to_string(v) + ": " : "";
    if (const common::Status why = check_view(views[v].cloud); !why.ok())
      return stop(kInput, name + "malformed cloud: " + why.message);
    if (!views[v].T_ref_camera.matrix().allFinite()) return stop(kInput, name + "camera pose is not finite");
    total += views[v].cloud.size();
  }
  if (total == 0) return stop(kInput, "empty cloud");

  auto t0 = Clock::now();
  const std::string hsi_reason = filter_views(views, params_.hsi, r);
  r.times.hsi_ms = ms_since(t0);
  r.red_points = r.red_xyz.size();
  if (r.red_xyz.empty()) return stop(kHsi, hsi_reason);

  t0 = Clock::now();
  ColorCloud red;
  red.xyz = r.red_xyz;
  red.rgb.assign(red.xyz.size(), Rgb{0, 0, 0});
  red.width = static_cast<int>(red.xyz.size());
  Indices all(red.xyz.size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = static_cast<int>(k);
  r.branch = cluster_branches(red, all, params_.branch, r.viewpoints);
  r.times.branch_ms = ms_since(t0);
  const Cluster* branch = r.branch.branch();
  if (!branch) return stop(kBranch, r.branch.status.message);

  t0 = Clock::now();
  r.smoothed = smooth_mls(r.red_xyz, branch->indices, params_.smoothing, r.viewpoints, r.red_view);
  r.times.smoothing_ms = ms_since(t0);
  if (r.smoothed.points.empty()) return stop(kSmoothing, r.smoothed.status.message);

  t0 = Clock::now();
  r.segmentation = segment_spheres(r.smoothed.points, r.smoothed.normals, params_.spheres, r.viewpoints);
  if (r.segmentation.spheres.empty()) {
    const SphereSegmentation& s = r.segmentation;
    return stop(kSpheres, "no sphere found: " + (s.status.ok() ? s.stop_reason : s.status.message));
  }
  correct_spheres(r, params_, r.segmentation.spheres);
  r.times.spheres_ms = ms_since(t0);

  if (params_.pedicel.enabled) {
    t0 = Clock::now();
    r.green = gather_green(views, r.segmentation.spheres, r.viewpoints, params_.pedicel);
    r.times.green_ms = ms_since(t0);
  }

  t0 = Clock::now();
  for (const auto& f : r.segmentation.spheres) {
    Tomato t;
    t.fit = f;
    r.tomatoes.push_back(std::move(t));
  }
  reason(r);
  r.times.reasoning_ms = ms_since(t0);
  r.status = {};
  return r;
}

PipelineResult TomatoPipeline::reason_about(const std::vector<SphereFit>& spheres) const {
  PipelineResult r;
  if (spheres.empty()) return stopped(r, PipelineStage::kSpheres, "no spheres to reason about");
  const auto t0 = Clock::now();
  for (const auto& f : spheres) {
    if (!f.sphere.centre.allFinite() || !(f.sphere.radius_m > 0)) {
      r.tomatoes.clear();
      return stopped(r, PipelineStage::kInput, "a sphere has a non-finite centre or a radius <= 0");
    }
    Tomato t;
    t.fit = f;
    r.tomatoes.push_back(std::move(t));
  }
  reason(r);
  r.times.reasoning_ms = ms_since(t0);
  r.status = {};
  return r;
}

void TomatoPipeline::reason(PipelineResult& r) const {
  std::vector<Sphere> spheres;
  for (const auto& t : r.tomatoes) spheres.push_back(t.fit.sphere);
  r.edges = contact_graph(spheres, params_.force.contact_tolerance_m);
  auto peds = estimate_pedicels(spheres, r.edges, params_.gravity, params_.force);
  for (std::size_t i = 0; i < r.tomatoes.size() && i < peds.size(); ++i) {
    Tomato& t = r.tomatoes[i];
    t.pedicel_prior = peds[i];
    if (!params_.pedicel.enabled || r.green.xyz.empty()) continue;
    const double cut_distance = spheres[i].radius_m + params_.cut.cut_offset_m;
    t.sighting =
        sight_pedicel(r.green, spheres, static_cast<int>(i), peds[i].expected_dir, cut_distance, params_.pedicel);
    peds[i] = pedicel_posterior(peds[i], t.sighting, params_.gravity);
  }
  const auto costs = pick_order(spheres, peds, params_.gravity, params_.pick, params_.force.contact_tolerance_m);
  for (std::size_t i = 0; i < r.tomatoes.size(); ++i) {
    Tomato& t = r.tomatoes[i];
    t.pedicel = peds[i];
    t.cut = plan_cut(spheres, static_cast<int>(i), peds[i], params_.cut);
    cut_on_seen_pedicel(spheres[i], t.sighting, params_.pedicel.cone_deg, t.cut);
  }
  for (std::size_t rank = 0; rank < costs.size(); ++rank) {
    Tomato& t = r.tomatoes[static_cast<std::size_t>(costs[rank].sphere)];
    t.cost = costs[rank];
    t.pick_rank = static_cast<int>(rank);
    r.pick_order.push_back(costs[rank].sphere);
  }
}

}  // namespace tinyline::tomato_reasoning
