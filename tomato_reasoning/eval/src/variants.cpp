#include "tomato_reasoning/eval/variants.hpp"

#include <functional>
#include <map>
#include <stdexcept>

namespace tinyline::tomato_reasoning::eval {

namespace {

class Ours : public Variant {
 public:
  explicit Ours(PipelineParams p) : p_(std::move(p)) { (void)TomatoPipeline(p_); }  // validates
  PipelineResult run(const Scenario& s) const override {
    PipelineParams p = p_;
    p.gravity = s.gravity_camera;
    std::vector<View> views;
    for (std::size_t v = 0; v < s.clouds.size(); ++v) views.push_back(View{s.clouds[v], s.T_ref_camera[v]});
    return TomatoPipeline(p).run(views);
  }

 private:
  PipelineParams p_;
};

using Setter = std::function<void(PipelineParams&, double)>;
const std::map<std::string, Setter>& setters() {
  static const std::map<std::string, Setter> m = {
      {"hsi.h_min_deg", [](PipelineParams& p, double v) { p.hsi.h_min_deg = v; }},
      {"hsi.h_max_deg", [](PipelineParams& p, double v) { p.hsi.h_max_deg = v; }},
      {"hsi.s_min", [](PipelineParams& p, double v) { p.hsi.s_min = int(v); }},
      {"hsi.s_max", [](PipelineParams& p, double v) { p.hsi.s_max = int(v); }},
      {"hsi.i_min", [](PipelineParams& p, double v) { p.hsi.i_min = int(v); }},
      {"hsi.i_max", [](PipelineParams& p, double v) { p.hsi.i_max = int(v); }},
      {"branch.tolerance_m", [](PipelineParams& p, double v) { p.branch.tolerance_m = v; }},
      {"branch.min_points", [](PipelineParams& p, double v) { p.branch.min_points = int(v); }},
      {"smoothing.voxel_m", [](PipelineParams& p, double v) { p.smoothing.voxel_m = v; }},
      {"smoothing.search_radius_m", [](PipelineParams& p, double v) { p.smoothing.search_radius_m = v; }},
      {"smoothing.polynomial_order", [](PipelineParams& p, double v) { p.smoothing.polynomial_order = int(v); }},
      {"spheres.radius_min_m", [](PipelineParams& p, double v) { p.spheres.radius_min_m = v; }},
      {"spheres.radius_max_m", [](PipelineParams& p, double v) { p.spheres.radius_max_m = v; }},
      {"spheres.inlier_distance_m", [](PipelineParams& p, double v) { p.spheres.inlier_distance_m = v; }},
      {"spheres.normal_tolerance_deg", [](PipelineParams& p, double v) { p.spheres.normal_tolerance_deg = v; }},
      {"spheres.hypothesis", [](PipelineParams& p, double v) {
         p.spheres.hypothesis = v == 4 ? SphereHypothesis::kFourPoints : SphereHypothesis::kTwoPointsWithNormals;
       }},
      {"spheres.max_iterations", [](PipelineParams& p, double v) { p.spheres.max_iterations = int(v); }},
      {"spheres.confidence", [](PipelineParams& p, double v) { p.spheres.confidence = v; }},
      {"spheres.local_sampling", [](PipelineParams& p, double v) { p.spheres.local_sampling = v != 0; }},
      {"spheres.min_inliers", [](PipelineParams& p, double v) { p.spheres.min_inliers = int(v); }},
      {"spheres.min_remaining", [](PipelineParams& p, double v) { p.spheres.min_remaining = int(v); }},
      {"spheres.max_failed_rounds", [](PipelineParams& p, double v) { p.spheres.max_failed_rounds = int(v); }},
      {"spheres.max_overlap_m", [](PipelineParams& p, double v) { p.spheres.max_overlap_m = v; }},
      {"spheres.removal_factor", [](PipelineParams& p, double v) { p.spheres.removal_factor = v; }},
      {"spheres.refine", [](PipelineParams& p, double v) { p.spheres.refine = v != 0; }},
      {"force.contact_tolerance_m", [](PipelineParams& p, double v) { p.force.contact_tolerance_m = v; }},
      {"force.eps_mean", [](PipelineParams& p, double v) { p.force.eps_mean = v; }},
      {"force.eps_variance", [](PipelineParams& p, double v) { p.force.eps_variance = v; }},
      {"force.weight_exponent", [](PipelineParams& p, double v) { p.force.weight_exponent = v; }},
      {"force.kernel_kappa", [](PipelineParams& p, double v) { p.force.kernel_kappa = v; }},
      {"force.samples", [](PipelineParams& p, double v) { p.force.samples = int(v); }},
      {"cut.cut_offset_m", [](PipelineParams& p, double v) { p.cut.cut_offset_m = v; }},
  };
  return m;
}

}  // namespace

std::vector<std::string> variant_names() {
  return {"default", "four_points", "thesis_model", "no_voxel", "plane_mls", "global_sampling", "no_refine"};
}

PipelineParams variant_params(const std::string& name) {
  PipelineParams p;
  if (name == "default") return p;
  if (name == "four_points") {
    p.spheres.hypothesis = SphereHypothesis::kFourPoints;
    return p;
  }
  if (name == "thesis_model") {  // the force model exactly as written: theta r weights, no kernel
    p.force.weight_exponent = 1.0;
    p.force.kernel_kappa = 0.0;
    return p;
  }
  if (name == "no_voxel") {
    p.smoothing.voxel_m = 0.0;
    return p;
  }
  if (name == "plane_mls") {
    p.smoothing.polynomial_order = 1;
    return p;
  }
  if (name == "global_sampling") {
    p.spheres.local_sampling = false;
    return p;
  }
  if (name == "no_refine") {
    p.spheres.refine = false;
    return p;
  }
  throw std::invalid_argument("unknown variant '" + name + "'");
}

std::unique_ptr<Variant> make_variant(const std::string& name, const PipelineParams& params) {
  (void)name;
  return std::make_unique<Ours>(params);
}

std::vector<std::string> param_keys() {
  std::vector<std::string> k;
  for (const auto& [key, fn] : setters()) k.push_back(key);
  return k;
}

void set_param(PipelineParams& p, const std::string& key, const std::string& value) {
  const auto it = setters().find(key);
  if (it == setters().end()) throw std::invalid_argument("unknown parameter '" + key + "' (see --help)");
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != value.size()) throw std::invalid_argument("parameter '" + key + "': '" + value + "' is not a number");
  it->second(p, v);
}

}  // namespace tinyline::tomato_reasoning::eval
