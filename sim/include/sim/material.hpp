// SPDX-License-Identifier: Apache-2.0
// Surface materials as the tiny TOF sensor (905 nm) and an RGB camera see them.
//
// The 905 nm return is a Lambertian lobe plus an optional specular (Phong)
// lobe for metals:  pi * f_r = albedo + specular * (n + 2) / 2 * cos^n(alpha_h),
// alpha_h the angle between the surface normal and the half vector of the
// emitter and receiver directions. "Effective albedo" below is pi * f_r at
// normal incidence, the quantity the sensor's reflectance figure measures.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace tinyline::sim {

using MaterialId = std::int32_t;
inline constexpr MaterialId kNoMaterial = -1;

struct Material {
  std::string name;
  double albedo = 0.5;                 ///< Lambertian reflectance at 905 nm [0, 1]
  double specular = 0.0;               ///< weight k_s of the specular lobe (0 = matte)
  double specular_exponent = 1.0;      ///< Phong exponent n of the lobe (larger = glossier)
  Eigen::Vector3d rgb{0.5, 0.5, 0.5};  ///< linear RGB albedo in [0, 1], for cameras
  /// The sensor's reflectance figure this material was set from (Table 3.2,
  /// (a+b)/pulse at 30 cm, normal incidence); NaN when not from the table.
  double reflectance_figure = std::numeric_limits<double>::quiet_NaN();

  /// pi * BRDF for light arriving along -to_emitter and leaving along to_receiver
  /// (all unit vectors; normal faces the viewer). Dimensionless, >= 0.
  [[nodiscard]] double return_factor(const Eigen::Vector3d& normal, const Eigen::Vector3d& to_emitter,
                                     const Eigen::Vector3d& to_receiver) const;
  /// pi * f_r at normal incidence (monostatic).
  [[nodiscard]] double effective_albedo() const { return albedo + specular * (specular_exponent + 2.0) / 2.0; }
};

/// Materials by name. The built-in library holds the nine materials of thesis
/// Table 3.2 (their albedo set from the reported reflectance figure, white
/// paper = albedo 0.80 at 905 nm) and a few generic ones for task scenes.
class MaterialLibrary {
 public:
  static MaterialLibrary builtin();

  /// Adds or replaces (same name) a material; returns its id. Ids of existing
  /// materials never change.
  MaterialId add(Material m);
  [[nodiscard]] std::optional<MaterialId> find(std::string_view name) const;
  [[nodiscard]] const Material& get(MaterialId id) const { return materials_.at(static_cast<std::size_t>(id)); }
  [[nodiscard]] std::size_t size() const { return materials_.size(); }
  [[nodiscard]] const std::vector<Material>& all() const { return materials_; }

 private:
  std::vector<Material> materials_;
};

/// Albedo of white paper at 905 nm, the anchor of the reflectance figures.
inline constexpr double kWhitePaperAlbedo = 0.80;
/// Table 3.2's reflectance figure of white paper [(a+b) per pulse at 30 cm].
inline constexpr double kWhitePaperFigure = 6.92;

}  // namespace tinyline::sim
