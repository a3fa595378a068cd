// SPDX-License-Identifier: Apache-2.0
// The steps of the two-stage clustering's edge filter and summaries
// (two_stage.cpp), on their own so their contracts can be tested (not installed).
#pragma once

#include <cstddef>

#include "laser_clustering/line_scan.hpp"
#include "laser_clustering/two_stage.hpp"

namespace tinyline::laser_clustering::detail {

/// Bound on EdgeFilterParams::reference_px (the median works on the stack).
constexpr int kMaxReferencePx = 16;

/// The median of r[from..to] (inclusive, 1 to kMaxReferencePx values): the
/// element std::nth_element puts at the middle (the upper one of an even count).
double reference_median(const double* r, int from, int to);

/// A mixed pixel: its neighbours differ by more than mixed_step_m +
/// step_per_m * (the nearer range), and its own range lies in the middle half
/// of that step (at least a quarter of it from either side).
bool is_mixed_pixel(double before, double at, double after, const EdgeFilterParams& e);

/// The positions a piece keeps after peeling its dragged ends.
struct EdgePeel {
  int lo;  ///< first kept position
  int hi;  ///< last kept position
};

/// Peels from each end of r[first..last] up to edge_width_px positions that
/// differ from the median of the reference_px inner ones by more than
/// step_m + step_per_m * that median, keeping at least min_keep_px.
EdgePeel peel_dragged_ends(const double* r, int first, int last, const EdgeFilterParams& e);

/// The mean of the ranges r[j], j in [k - h, k + h] within [lo, hi] (h =
/// smooth_half_width_px), that lie within smooth_step_m + step_per_m * r[k]
/// of r[k]: smoothing that never averages across a depth step.
double smoothed_range(const double* r, int k, int lo, int hi, const EdgeFilterParams& e);

/// Whether one of the next two valid pixels beyond edge_pixel (in direction
/// dir, +1 or -1) is nearer than edge_range_m by more than mixed_step_m +
/// step_per_m * edge_range_m (two, because the first may be a mixed pixel).
bool in_front(const LineScan& scan, double edge_range_m, std::size_t edge_pixel, int dir, const EdgeFilterParams& e);

}  // namespace tinyline::laser_clustering::detail
