// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/variants.hpp"

#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

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

// OpenCV's colour segmentation on the organised image in place of the
// per-point HSI filter (what a vision engineer would write): a mask of red
// pixels (OpenCV's HSV, or the HSI filter's own test per pixel), opened and
// closed, components under a minimum area dropped. Pixels outside the mask
// lose their depth and the HSI filter is opened wide, so the mask alone
// decides which points go on to the branch clustering.
struct ImageSegmentation {
  bool hsv = true;                ///< false: the HSI filter's test (the pipeline's hsi parameters) per pixel
  int hue_half_deg = 15;          ///< HSV: |hue - red| at most this [deg]
  int s_min = 100;                ///< HSV saturation [0, 255]
  int v_min = 25, v_max = 230;    ///< HSV value [0, 255]
  int open_px = 0, close_px = 0;  ///< elliptic structuring elements (0: none)
  int min_area_px = 0;            ///< smaller 8-connected components are dropped
};

ImageSegmentation parse_segmentation(const std::string& name) {
  // opencv_hsv[:key=value]... or opencv_hsi[:key=value]...
  ImageSegmentation g;
  g.hsv = name.rfind("opencv_hsv", 0) == 0;
  std::stringstream ss(name);
  std::string item;
  std::getline(ss, item, ':');
  const std::map<std::string, int*> keys = {{"hh", &g.hue_half_deg}, {"s", &g.s_min},      {"vmin", &g.v_min},
                                            {"vmax", &g.v_max},      {"open", &g.open_px}, {"close", &g.close_px},
                                            {"area", &g.min_area_px}};
  while (std::getline(ss, item, ':')) {
    const auto eq = item.find('=');
    const auto it = keys.find(item.substr(0, eq));
    if (eq == std::string::npos || it == keys.end())
      throw std::invalid_argument("variant '" + name + "': '" + item +
                                  "' is not one of hh, s, vmin, vmax, open, close, area =N");
    *it->second = std::stoi(item.substr(eq + 1));
  }
  return g;
}

cv::Mat red_mask(const ColorCloud& c, const ImageSegmentation& g, const HsiFilterParams& hsi) {
  // The colour image exists where depth does not: segment all of it.
  const cv::Mat rgb(c.height, c.width, CV_8UC3, const_cast<Rgb*>(c.rgb.data()));  // NOLINT: read only
  cv::Mat mask;
  if (g.hsv) {
    cv::Mat hsv, low, high;
    cv::cvtColor(rgb, hsv, cv::COLOR_RGB2HSV);  // H in [0, 180): 2 deg per step
    const int hh = (g.hue_half_deg + 1) / 2;
    cv::inRange(hsv, cv::Scalar(0, g.s_min, g.v_min), cv::Scalar(hh, 255, g.v_max), low);
    cv::inRange(hsv, cv::Scalar(180 - hh, g.s_min, g.v_min), cv::Scalar(180, 255, g.v_max), high);
    mask = low | high;
  } else {
    const HsiFilter f(hsi);
    mask = cv::Mat(c.height, c.width, CV_8U);
    for (std::size_t i = 0; i < c.size(); ++i) mask.data[i] = f.passes(c.rgb[i]) ? 255 : 0;
  }
  if (g.open_px > 0)
    cv::morphologyEx(mask, mask, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {g.open_px, g.open_px}));
  if (g.close_px > 0)
    cv::morphologyEx(mask, mask, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, {g.close_px, g.close_px}));
  if (g.min_area_px > 0) {
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    std::vector<std::uint8_t> keep(std::size_t(n), 0);
    for (int l = 1; l < n; ++l) keep[std::size_t(l)] = stats.at<int>(l, cv::CC_STAT_AREA) >= g.min_area_px ? 255 : 0;
    for (std::size_t i = 0; i < c.size(); ++i) mask.data[i] = keep[std::size_t(labels.at<int>(int(i)))];
  }
  return mask;
}

class OpenCvSegmented : public Variant {
 public:
  OpenCvSegmented(PipelineParams p, ImageSegmentation g) : mask_hsi_(p.hsi), g_(g), p_(std::move(p)) {
    p_.hsi = HsiFilterParams{-180, 180, 0, 255, 0, 255};  // the mask decides
    (void)TomatoPipeline(p_);
  }
  PipelineResult run(const Scenario& s) const override {
    PipelineParams p = p_;
    p.gravity = s.gravity_camera;
    std::vector<ColorCloud> masked(s.clouds);
    std::vector<View> views;
    for (std::size_t v = 0; v < masked.size(); ++v) {
      ColorCloud& c = masked[v];
      const cv::Mat m = red_mask(c, g_, mask_hsi_);
      for (std::size_t i = 0; i < c.size(); ++i)
        if (m.data[i] == 0) c.xyz[i].setConstant(std::numeric_limits<float>::quiet_NaN());
      views.push_back(View{c, s.T_ref_camera[v]});
    }
    return TomatoPipeline(p).run(views);
  }

 private:
  HsiFilterParams mask_hsi_;
  ImageSegmentation g_;
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
      {"spheres.hypothesis",
       [](PipelineParams& p, double v) {
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
      {"pedicel.enabled", [](PipelineParams& p, double v) { p.pedicel.enabled = v != 0; }},
      {"pedicel.green_margin", [](PipelineParams& p, double v) { p.pedicel.green_margin = int(v); }},
      {"pedicel.shell_inner_m", [](PipelineParams& p, double v) { p.pedicel.shell_inner_m = v; }},
      {"pedicel.shell_outer_m", [](PipelineParams& p, double v) { p.pedicel.shell_outer_m = v; }},
      {"pedicel.max_prior_angle_deg", [](PipelineParams& p, double v) { p.pedicel.max_prior_angle_deg = v; }},
      {"pedicel.cone_deg", [](PipelineParams& p, double v) { p.pedicel.cone_deg = v; }},
      {"pedicel.calyx_depth_m", [](PipelineParams& p, double v) { p.pedicel.calyx_depth_m = v; }},
      {"pedicel.direction_source", [](PipelineParams& p, double v) { p.pedicel.direction_source = int(v); }},
      {"pedicel.calyx_cone_deg", [](PipelineParams& p, double v) { p.pedicel.calyx_cone_deg = v; }},
      {"pedicel.line_reach_m", [](PipelineParams& p, double v) { p.pedicel.line_reach_m = v; }},
      {"pedicel.min_points", [](PipelineParams& p, double v) { p.pedicel.min_points = int(v); }},
      {"pedicel.min_pedicel_points", [](PipelineParams& p, double v) { p.pedicel.min_pedicel_points = int(v); }},
      {"pedicel.rod_radius_m", [](PipelineParams& p, double v) { p.pedicel.rod_radius_m = v; }},
      {"pedicel.kappa_per_point", [](PipelineParams& p, double v) { p.pedicel.kappa_per_point = v; }},
      {"pedicel.kappa_max", [](PipelineParams& p, double v) { p.pedicel.kappa_max = v; }},
      {"pick.edge_softness_m", [](PipelineParams& p, double v) { p.pick.edge_softness_m = v; }},
      {"noise_bias.enabled", [](PipelineParams& p, double v) { p.noise_bias.enabled = v != 0; }},
      {"noise_bias.radius_per_var", [](PipelineParams& p, double v) { p.noise_bias.radius_per_var = v; }},
      {"noise_bias.centre_per_var", [](PipelineParams& p, double v) { p.noise_bias.centre_per_var = v; }},
  };
  return m;
}

}  // namespace

std::vector<std::string> variant_names() {
  return {"default",
          "four_points",
          "thesis_model",
          "no_voxel",
          "plane_mls",
          "global_sampling",
          "no_refine",
          "opencv_hsv[:hh=15:s=100:vmin=25:vmax=230:open=0:close=0:area=0]",
          "opencv_hsi[:open=0:close=0:area=0]"};
}

PipelineParams variant_params(const std::string& name) {
  PipelineParams p;
  if (name == "default" || name.rfind("opencv_hsv", 0) == 0 || name.rfind("opencv_hsi", 0) == 0) return p;
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
  if (name.rfind("opencv_hsv", 0) == 0 || name.rfind("opencv_hsi", 0) == 0)
    return std::make_unique<OpenCvSegmented>(params, parse_segmentation(name));
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
