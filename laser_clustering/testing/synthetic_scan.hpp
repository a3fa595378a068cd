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

inline SynthScan synth_scan(const std::vector<Disc>& discs, const SynthParams& p) {
  SynthScan out;
  std::mt19937 rng(p.seed);
  std::normal_distribution<double> noise(0.0, p.noise_sd_m);
  const double pitch = p.fov_rad / (p.pixels - 1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto hit = [&](double a, int& id, double& refl) {
    const double dx = std::sin(a), dz = std::cos(a);
    double best = std::numeric_limits<double>::infinity();
    id = -1;
    for (const auto& d : discs) {
      const double b = dx * d.x_m + dz * d.z_m;
      const double c = d.x_m * d.x_m + d.z_m * d.z_m - d.radius_m * d.radius_m;
      const double disc = b * b - c;
      if (disc < 0.0) continue;
      const double t = b - std::sqrt(disc);
      if (t > 0.0 && t < best) {
        best = t;
        id = d.id;
        refl = d.reflectance;
      }
    }
    if (p.wall_z_m && dz > 0.0) {
      const double t = *p.wall_z_m / dz;
      if (t < best) {
        best = t;
        id = 0;
        refl = p.wall_reflectance;
      }
    }
    return best;
  };
  for (int i = 0; i < p.pixels; ++i) {
    const double a = -p.fov_rad / 2 + pitch * i;
    out.scan.angle_rad.push_back(a);
    double sw = 0.0, swr = 0.0, swref = 0.0;
    std::vector<std::pair<int, double>> energy;
    for (int s = 0; s < p.subrays; ++s) {
      const double as = a + pitch * ((s + 0.5) / p.subrays - 0.5);
      int id;
      double refl = 0.0;
      const double t = hit(as, id, refl);
      if (!std::isfinite(t) || t > p.max_range_m) continue;
      const double w = refl / (t * t);
      sw += w;
      swr += w * t;
      swref += refl;
      auto it = std::find_if(energy.begin(), energy.end(), [&](auto& e) { return e.first == id; });
      if (it == energy.end()) {
        energy.emplace_back(id, w);
      } else {
        it->second += w;
      }
    }
    if (sw <= 0.0) {
      out.scan.range_m.push_back(nan);
      out.scan.reflectance.push_back(nan);
      out.truth.push_back(-1);
      out.purity.push_back(1.0);
      continue;
    }
    out.scan.range_m.push_back(swr / sw);
    out.scan.reflectance.push_back(swref / p.subrays);
    const auto dominant =
        std::max_element(energy.begin(), energy.end(), [](auto& l, auto& r) { return l.second < r.second; });
    out.truth.push_back(dominant->first);
    out.purity.push_back(dominant->second / sw);
  }
  // Emitter-side drag: the near object's edge pixels facing the emitter read long.
  if (p.drag_m > 0.0) {
    const int s = p.emitter_side;
    std::vector<double> base = out.scan.range_m;
    for (int i = 0; i < p.pixels; ++i) {
      const int j = i + s;
      if (j < 0 || j >= p.pixels || out.truth[static_cast<std::size_t>(i)] <= 0) continue;
      const double ri = base[static_cast<std::size_t>(i)], rj = base[static_cast<std::size_t>(j)];
      const bool edge = out.truth[static_cast<std::size_t>(j)] != out.truth[static_cast<std::size_t>(i)] &&
                        (!std::isfinite(rj) || rj > ri + 0.01);
      if (!edge) continue;
      for (int k = 0; k < p.drag_px; ++k) {
        const int q = i - s * k;
        if (q < 0 || q >= p.pixels || out.truth[static_cast<std::size_t>(q)] != out.truth[static_cast<std::size_t>(i)])
          break;
        out.scan.range_m[static_cast<std::size_t>(q)] += p.drag_m / (1 << (2 * k));
      }
    }
  }
  for (auto& r : out.scan.range_m) {
    if (std::isfinite(r)) r += noise(rng);
  }
  return out;
}

}  // namespace tinyline::laser_clustering::test
