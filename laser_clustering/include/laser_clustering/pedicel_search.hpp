// SPDX-License-Identifier: Apache-2.0
// Pedicel search: a short sweep of the laser plane along the expected
// pedicel, fused into one picture of the thin objects above the fruit.
//
// One scan sees a pedicel as a thin object and nothing more: a neighbour's
// pedicel, the peduncle crossing the plane, a sepal's tip or a leaf's edge
// look the same, and the target's own pedicel may be hidden at that height
// by a fruit in front. A few scans with the plane moved along the expected
// pedicel (the arm's one free direction while the blades stay square to
// it) tell them apart: a pedicel crosses every plane near where the one
// below put it, along the expected direction, while the peduncle and leaves
// cross at a slant and a sepal's tip shows in one plane only. The search
// fits lines through the candidates of the planes (tracks), scores each by
// how many planes see it, how well its direction agrees with the expected
// pedicel's and how near it passes where the pedicel is expected (the
// target's top, fixed by the vision and the tomato look), and answers for
// the plane at height 0, as find_pedicel would.
//
// Frames: the laser frame of the height-0 scan (z forward along the optical
// axis, x along the line, y = z x x across the plane, + away from the
// fruit); the scan at height h is that frame moved by h along y.
#pragma once

#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "laser_clustering/pedicel_finder.hpp"

namespace tinyline::laser_clustering {

struct PedicelSearchParams {
  /// Heights of the sweep's planes along the expected pedicel (laser y, +
  /// away from the fruit) [m]; 0 is the plane of the planned cut. The plan:
  /// scan them in this order.
  std::vector<double> heights_m{0.0, -0.005, 0.005, -0.01, 0.01};
  /// A candidate within this of a track's line in its plane supports it [m]
  /// (range noise, a pedicel's width, the arm's repeatability).
  double link_m = 0.005;
  /// Spread of a track's slope (dx/dy and dz/dy) around the expected
  /// direction's, which is 0: the vision's direction error (0.3: 17 deg).
  double slope_sd = 0.3;
  /// Steeper tracks are no pedicel (a peduncle or a leaf crossing the planes
  /// at a slant); 1: 45 deg off the expected direction.
  double max_slope = 1.0;
  /// Factor for each plane in view where no candidate lies on the track
  /// (the pedicel hidden there, or no pedicel at all), in (0, 1].
  double miss_factor = 0.35;
  /// Planes that must see a track for it to be a pedicel (1: any candidate).
  int min_planes = 2;
};

common::Validation validate(const PedicelSearchParams& params);

/// One plane of the sweep: its height and the finder's answer there (its
/// candidates are what the search fuses; find_pedicel with the expectation
/// of the height-0 plane, whose gate keeps far objects out).
struct SweepScan {
  double height_m = 0.0;
  PedicelDetection detection;
};

/// A line through candidates of several planes: x and z as functions of the
/// height, position + slope * height.
struct PedicelTrack {
  Eigen::Vector2d position_xz_m = Eigen::Vector2d::Zero();  ///< where it crosses the height-0 plane [m]
  Eigen::Vector2d slope = Eigen::Vector2d::Zero();          ///< d(x, z) / d height
  int planes_seen = 0;                                      ///< planes with a candidate on it
  double nearest_seen_height_m = 0.0;  ///< of those planes, the height nearest 0 (above on a tie) [m]
  double quality = 0.0;                ///< its candidates' shape and isolation, averaged over the planes seeing it
  double support = 0.0;  ///< product over the planes of the seen ones' fit and the missed ones' miss_factor
  double prior = 0.0;    ///< position (at height 0) and slope against the expectation, in (0, 1]
  double weight = 0.0;   ///< quality * support * prior
};

struct PedicelSearchResult {
  /// Where to cut: the height-0 plane when the chosen track is seen there,
  /// else the plane nearest it that sees the track (the planned cut may lie
  /// below the calyx or above the pedicel's top) [m].
  double cut_height_m = 0.0;
  /// The answer in the plane at cut_height_m, as find_pedicel's: the chosen
  /// track's crossing as the pedicel (its candidates are the tracks' crossings,
  /// best first, cluster -1), or the height-0 scan's own answer when no
  /// track is a pedicel (kNothingToCut with the reason when the sweep saw
  /// candidates but none on a track that enough planes see).
  PedicelDetection detection;
  std::vector<PedicelTrack> tracks;  ///< best first, each distinct
  int planes = 0;                    ///< planes fused
};

/// Fuses the sweep's planes. `expected` is where the pedicel is expected in
/// the height-0 plane (position, spread, gate); one of the scans must be at
/// height 0. Bad parameters or no height-0 scan give kInvalidInput with the
/// reason, never an exception.
[[nodiscard]] PedicelSearchResult fuse_sweep(std::span<const SweepScan> scans, const PedicelFinderParams& finder,
                                             const PedicelExpectation& expected,
                                             const PedicelSearchParams& params = {});

}  // namespace tinyline::laser_clustering
