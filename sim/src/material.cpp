// SPDX-License-Identifier: Apache-2.0
#include <sim/material.hpp>

#include <algorithm>
#include <cmath>

namespace tinyline::sim {

double Material::return_factor(const Eigen::Vector3d& normal, const Eigen::Vector3d& to_emitter,
                               const Eigen::Vector3d& to_receiver) const {
  double f = albedo;
  if (specular > 0.0) {
    Eigen::Vector3d h = to_emitter + to_receiver;
    const double hn = h.norm();
    if (hn > 1e-12) {
      const double c = std::max(0.0, normal.dot(h / hn));
      f += specular * (specular_exponent + 2.0) / 2.0 * std::pow(c, specular_exponent);
    }
  }
  return f;
}

MaterialId MaterialLibrary::add(Material m) {
  if (auto id = find(m.name)) {
    materials_[static_cast<std::size_t>(*id)] = std::move(m);
    return *id;
  }
  materials_.push_back(std::move(m));
  return static_cast<MaterialId>(materials_.size() - 1);
}

std::optional<MaterialId> MaterialLibrary::find(std::string_view name) const {
  for (std::size_t i = 0; i < materials_.size(); ++i) {
    if (materials_[i].name == name) return static_cast<MaterialId>(i);
  }
  return std::nullopt;
}

namespace {

// A matte material whose effective albedo follows Table 3.2's figure.
Material from_figure(std::string name, double figure, Eigen::Vector3d rgb) {
  Material m;
  m.name = std::move(name);
  m.albedo = kWhitePaperAlbedo * figure / kWhitePaperFigure;
  m.rgb = rgb;
  m.reflectance_figure = figure;
  return m;
}

// A metal: a small diffuse part plus a Phong lobe sized so that the normal-
// incidence return matches the figure. The exponent sets how quickly the
// return falls off when the sensor tilts (Section 5.3.2 aligns on its peak).
Material metal(std::string name, double figure, double diffuse, double exponent, Eigen::Vector3d rgb) {
  Material m;
  m.name = std::move(name);
  m.albedo = diffuse;
  m.specular_exponent = exponent;
  const double target = kWhitePaperAlbedo * figure / kWhitePaperFigure;
  m.specular = std::max(0.0, target - diffuse) * 2.0 / (exponent + 2.0);
  m.rgb = rgb;
  m.reflectance_figure = figure;
  return m;
}

Material matte(std::string name, double albedo, Eigen::Vector3d rgb) {
  Material m;
  m.name = std::move(name);
  m.albedo = albedo;
  m.rgb = rgb;
  return m;
}

}  // namespace

MaterialLibrary MaterialLibrary::builtin() {
  MaterialLibrary lib;
  // Table 3.2 (sim/config/fidelity/thesis_measured.yaml materials_at_30cm).
  lib.add(from_figure("white_paper", 6.92, {0.90, 0.90, 0.88}));
  lib.add(from_figure("black_cushion", 4.6955, {0.04, 0.04, 0.05}));
  lib.add(metal("metal_pan", 25.0071, 0.30, 30.0, {0.55, 0.55, 0.56}));  // "without gloss": broad lobe
  lib.add(from_figure("cloth_bag", 5.1638, {0.10, 0.20, 0.55}));
  lib.add(from_figure("styrofoam", 4.8961, {0.15, 0.35, 0.75}));
  lib.add(from_figure("white_towel", 5.6881, {0.85, 0.85, 0.85}));
  lib.add(from_figure("cardboard", 4.7981, {0.55, 0.42, 0.28}));
  lib.add(metal("metal_wrench", 37.125, 0.20, 200.0, {0.70, 0.70, 0.72}));  // polished: narrow lobe
  lib.add(from_figure("ic_foam", 0.5699, {0.03, 0.03, 0.03}));
  // Generic materials for task scenes (905 nm albedo, camera colour).
  lib.add(matte("white_matte", 0.90, {0.90, 0.90, 0.90}));
  lib.add(matte("grey_matte", 0.45, {0.45, 0.45, 0.45}));
  lib.add(matte("black_matte", 0.05, {0.04, 0.04, 0.04}));
  lib.add(matte("wall_paint", 0.75, {0.85, 0.84, 0.80}));
  lib.add(matte("wood", 0.55, {0.60, 0.45, 0.30}));
  lib.add(matte("panel_grey", 0.35, {0.35, 0.36, 0.38}));
  lib.add(metal("aluminium", 12.0, 0.35, 12.0, {0.75, 0.76, 0.78}));
  lib.add(matte("carbon_frame", 0.08, {0.08, 0.08, 0.08}));
  // Plants at 905 nm reflect strongly (the NIR plateau) while looking red or green.
  lib.add(matte("tomato_red", 0.55, {0.70, 0.06, 0.04}));
  lib.add(matte("tomato_green", 0.60, {0.35, 0.55, 0.12}));
  lib.add(matte("leaf", 0.50, {0.12, 0.35, 0.08}));
  lib.add(matte("stem", 0.45, {0.25, 0.45, 0.15}));
  return lib;
}

}  // namespace tinyline::sim
