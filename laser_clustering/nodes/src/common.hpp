// SPDX-License-Identifier: Apache-2.0
// Shared pieces of the laser_clustering nodes: message <-> core conversions
// and the one parameter no core struct holds. The core settings are declared
// from their tables (laser_clustering/param_tables.hpp).
#pragma once

#include <string>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/tinyline_msgs/line_clusters.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>

#include "laser_clustering/alignment_search.hpp"
#include "laser_clustering/pedicel_finder.hpp"
#include "laser_clustering/reflectance_clustering.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "laser_clustering/two_stage.hpp"

namespace tinyline::laser_clustering::nodes {

/// Fills `out` (reusing its buffers) from a LineScan message: a pixel is
/// valid when its status is STATUS_VALID, its distance finite and > 0 and,
/// when the message has reflectances and min_reflectance > 0, its
/// reflectance at least min_reflectance. Returns an empty string, or what is
/// wrong with the message (array lengths that disagree).
std::string to_core(const tinyline_msgs::msg::LineScan& msg, LineScan& out, double min_reflectance = 0.0);

/// Declares `min_reflectance`: returns dimmer than this count as no return.
/// The wire protocol's validity rule lets through pixels that see nothing
/// (the leakage of the longest read-out) and pixels lit by lens halo beside
/// a bright near object; both report ranges of nothing (docs/laser_clustering.md).
double declare_min_reflectance(bus::Node& node);

/// The message of a two-stage clustering.
void to_msg(const TwoStageResult& r, tinyline_msgs::msg::LineClusters& out);
/// The message of a reflectance clustering.
void to_msg(const ReflectanceClusteringResult& r, tinyline_msgs::msg::LineClusters& out);

}  // namespace tinyline::laser_clustering::nodes
