// SPDX-License-Identifier: Apache-2.0
// The pedicel finder's messages <-> the core's types, for the nodes and for
// a controller on the bus that runs the closed loop of thesis 4.5 itself:
// it reads the finder's PedicelDetection (from_msg), asks the core where to
// look next (expectation_after_move / expectation_after_centring) and
// publishes that as the next PedicelLayout (to_msg). Positions are in the
// scan's laser frame: x along the line, z forward; the messages' y is unused.
#pragma once

#include <string>

#include <tinyline/msg/tinyline_msgs/pedicel_detection.hpp>
#include <tinyline/msg/tinyline_msgs/pedicel_layout.hpp>

#include "laser_clustering/pedicel_finder.hpp"

namespace tinyline::laser_clustering {

/// The expectation a layout describes; its zeros take defaults:
/// expected_sd_m -> default_sd_m, neighbour_sd_m -> the core's, gate_sd -> no
/// gate. Returns what is wrong with the message and leaves `out` alone (a
/// half-read layout would blame the wrong candidates), or an empty string.
[[nodiscard]] std::string from_msg(const tinyline_msgs::msg::PedicelLayout& msg, double default_sd_m,
                                   PedicelExpectation& out);
/// The layout message of an expectation (the header is the caller's); an
/// infinite gate_sd goes on the wire as 0.
void to_msg(const PedicelExpectation& e, tinyline_msgs::msg::PedicelLayout& out);

/// A detection's message: the move, and every candidate's centre, weight
/// and width, best first (the header is the caller's).
void to_msg(const PedicelDetection& d, tinyline_msgs::msg::PedicelDetection& out);
/// The detection a message carries: the move and the candidates (centre,
/// weight, width; the per-factor scores are not on the wire), enough for
/// expectation_after_move. Returns what is wrong (an unknown outcome,
/// candidate arrays of different lengths) and leaves `out` alone, or an
/// empty string.
[[nodiscard]] std::string from_msg(const tinyline_msgs::msg::PedicelDetection& msg, PedicelDetection& out);

}  // namespace tinyline::laser_clustering
