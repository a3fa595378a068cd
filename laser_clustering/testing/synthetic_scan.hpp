// SPDX-License-Identifier: Apache-2.0
// Hand-made line scans for the unit tests and the benchmarks: a 2-D cut through the laser plane
// with discs (rods and spheres cut by the plane) and an optional wall, each
// pixel averaging several sub-rays weighted by received energy (mixed
// pixels), Gaussian range noise, and the emitter-side "distance drag" of
// thesis 4.4.2 added phenomenologically. The project's simulator (sim/)
// replaces this for the evaluation; these scans only need to be simple and
// known.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include "laser_clustering/line_scan.hpp"

namespace tinyline::laser_clustering::test {

struct Disc {
  double x_m, z_m, radius_m;
  double reflectance = 6.0;
  int id = 0;  ///< ground truth label (>= 1; 0 is the wall, -1 nothing)
};

struct SynthParams {
  int pixels = 256;
  double fov_rad = 70.0 * std::numbers::pi / 180.0;
  double noise_sd_m = 0.002;
  int subrays = 8;
  double max_range_m = 2.0;
  /// Range added to the emitter-side edge pixel of a near object, decaying inwards.
  double drag_m = 0.0;
  int drag_px = 2;
  int emitter_side = +1;  ///< +1: the emitter is on the +x side
  std::optional<double> wall_z_m;
  double wall_reflectance = 5.0;
  unsigned seed = 1;
};

struct SynthScan {
  LineScan scan;
  std::vector<int> truth;      ///< per pixel: id of the dominant object, 0 wall, -1 nothing
  std::vector<double> purity;  ///< per pixel: the dominant object's share of the received energy
};

namespace detail {

/// What one ray hits first: its range (infinity when nothing), the object's
/// id and reflectance.
struct RayHit {
  double range_m = std::numeric_limits<double>::infinity();
  int id = -1;
  double reflectance = 0.0;
};

inline RayHit cast_ray(double angle_rad, const std::vector<Disc>& discs, const SynthParams& p) {
  const double dx = std::sin(angle_rad), dz = std::cos(angle_rad);
  RayHit hit;
  for (const auto& d : discs) {
    const double b = dx * d.x_m + dz * d.z_m;
    const double c = d.x_m * d.x_m + d.z_m * d.z_m - d.radius_m * d.radius_m;
    const double disc = b * b - c;
    if (disc < 0.0) continue;
    const double t = b - std::sqrt(disc);
    if (t > 0.0 && t < hit.range_m) hit = {t, d.id, d.reflectance};
  }
  if (p.wall_z_m && dz > 0.0) {
    const double t = *p.wall_z_m / dz;
    if (t < hit.range_m) hit = {t, 0, p.wall_reflectance};
  }
  return hit;
}

/// One pixel: its sub-rays averaged by received energy (a mixed pixel reads
/// between its objects), the dominant object and its share.
inline void add_pixel(SynthScan& out, double angle_rad, double pitch_rad, const std::vector<Disc>& discs,
                      const SynthParams& p) {
  double sw = 0.0, swr = 0.0, swref = 0.0;
  std::vector<std::pair<int, double>> energy;
  for (int s = 0; s < p.subrays; ++s) {
    const RayHit h = cast_ray(angle_rad + pitch_rad * ((s + 0.5) / p.subrays - 0.5), discs, p);
    if (!std::isfinite(h.range_m) || h.range_m > p.max_range_m) continue;
    const double w = h.reflectance / (h.range_m * h.range_m);
    sw += w;
    swr += w * h.range_m;
    swref += h.reflectance;
    auto it = std::find_if(energy.begin(), energy.end(), [&](auto& e) { return e.first == h.id; });
    if (it == energy.end()) {
      energy.emplace_back(h.id, w);
    } else {
      it->second += w;
    }
  }
  out.scan.angle_rad.push_back(angle_rad);
  if (sw <= 0.0) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    out.scan.range_m.push_back(nan);
    out.scan.reflectance.push_back(nan);
    out.truth.push_back(-1);
    out.purity.push_back(1.0);
    return;
  }
  out.scan.range_m.push_back(swr / sw);
  out.scan.reflectance.push_back(swref / p.subrays);
  const auto dominant =
      std::max_element(energy.begin(), energy.end(), [](auto& l, auto& r) { return l.second < r.second; });
  out.truth.push_back(dominant->first);
  out.purity.push_back(dominant->second / sw);
}

/// Emitter-side drag: the near object's edge pixels facing the emitter read long.
inline void add_drag(SynthScan& out, const SynthParams& p) {
  const int s = p.emitter_side;
  const auto at = [](const auto& v, int i) { return v[static_cast<std::size_t>(i)]; };
  const std::vector<double> base = out.scan.range_m;
  for (int i = 0; i < p.pixels; ++i) {
    const int j = i + s;
    if (j < 0 || j >= p.pixels || at(out.truth, i) <= 0) continue;
    const double ri = at(base, i), rj = at(base, j);
    const bool edge = at(out.truth, j) != at(out.truth, i) && (!std::isfinite(rj) || rj > ri + 0.01);
    if (!edge) continue;
    for (int k = 0; k < p.drag_px; ++k) {
      const int q = i - s * k;
      if (q < 0 || q >= p.pixels || at(out.truth, q) != at(out.truth, i)) break;
      out.scan.range_m[static_cast<std::size_t>(q)] += p.drag_m / (1 << (2 * k));
    }
  }
}

}  // namespace detail

inline SynthScan synth_scan(const std::vector<Disc>& discs, const SynthParams& p) {
  SynthScan out;
  const double pitch = p.fov_rad / (p.pixels - 1);
  for (int i = 0; i < p.pixels; ++i) detail::add_pixel(out, -p.fov_rad / 2 + pitch * i, pitch, discs, p);
  if (p.drag_m > 0.0) detail::add_drag(out, p);
  std::mt19937 rng(p.seed);
  std::normal_distribution<double> noise(0.0, p.noise_sd_m);
  for (auto& r : out.scan.range_m) {
    if (std::isfinite(r)) r += noise(rng);
  }
  return out;
}

}  // namespace tinyline::laser_clustering::test
