// SPDX-License-Identifier: Apache-2.0
#include "laser_clustering/nodes/conversions.hpp"

#include <cmath>
#include <cstdint>
#include <limits>

#include <fmt/format.h>

namespace tinyline::laser_clustering {

namespace msgs = tinyline_msgs::msg;

namespace {

// The outcomes go on the wire as their enum values.
constexpr std::uint8_t wire(PedicelOutcome o) { return static_cast<std::uint8_t>(o); }
static_assert(wire(PedicelOutcome::kCutHere) == msgs::PedicelDetection::CUT_HERE);
static_assert(wire(PedicelOutcome::kMove) == msgs::PedicelDetection::MOVE);
static_assert(wire(PedicelOutcome::kNothingToCut) == msgs::PedicelDetection::NOTHING_TO_CUT);
static_assert(wire(PedicelOutcome::kOutOfView) == msgs::PedicelDetection::OUT_OF_VIEW);
static_assert(wire(PedicelOutcome::kInvalidInput) == msgs::PedicelDetection::INVALID_INPUT);

bool finite(const geometry_msgs::msg::Point& p) { return std::isfinite(p.x) && std::isfinite(p.z); }
Eigen::Vector2d xz(const geometry_msgs::msg::Point& p) { return {p.x, p.z}; }
geometry_msgs::msg::Point point(const Eigen::Vector2d& xz) {
  geometry_msgs::msg::Point p;
  p.x = xz.x();
  p.z = xz.y();
  return p;
}

std::string check(const msgs::PedicelLayout& l) {
  if (l.may_be_absent.size() != l.neighbours.size()) {
    return fmt::format("{} neighbours but {} may_be_absent flags", l.neighbours.size(), l.may_be_absent.size());
  }
  if (!finite(l.expected)) return "a non-finite expected pedicel";
  if (!(std::isfinite(l.expected_sd_m) && l.expected_sd_m >= 0.0) ||
      !(std::isfinite(l.neighbour_sd_m) && l.neighbour_sd_m >= 0.0)) {
    return fmt::format("expected_sd_m and neighbour_sd_m must be finite and >= 0 (got {} and {})", l.expected_sd_m,
                       l.neighbour_sd_m);
  }
  for (std::size_t i = 0; i < l.neighbours.size(); ++i) {
    if (!finite(l.neighbours[i])) return fmt::format("neighbour {} is not finite", i);
  }
  if (l.alternative_weights.size() != l.alternatives.size()) {
    return fmt::format("{} alternatives but {} alternative_weights", l.alternatives.size(),
                       l.alternative_weights.size());
  }
  for (std::size_t i = 0; i < l.alternatives.size(); ++i) {
    // The core's rule (PedicelExpectation::Alternative): a runner-up never
    // outweighs the expected pedicel, and weightless is absent.
    if (!finite(l.alternatives[i])) return fmt::format("alternative {} is not finite", i);
    if (!(l.alternative_weights[i] > 0.0 && l.alternative_weights[i] <= 1.0)) {
      return fmt::format("alternative {} has weight {}; a weight must be in (0, 1]", i, l.alternative_weights[i]);
    }
  }
  if (!(std::isfinite(l.gate_sd) && l.gate_sd >= 0.0)) {
    return fmt::format("gate_sd must be finite and >= 0 (0: no gate), got {}", l.gate_sd);
  }
  return {};
}

}  // namespace

std::string from_msg(const msgs::PedicelLayout& l, double default_sd_m, PedicelExpectation& out) {
  if (auto bad = check(l); !bad.empty()) return bad;
  PedicelExpectation e;
  e.position_xz_m = xz(l.expected);
  e.sd_m = l.expected_sd_m > 0.0 ? l.expected_sd_m : default_sd_m;
  if (l.neighbour_sd_m > 0.0) e.neighbour_sd_m = l.neighbour_sd_m;
  for (std::size_t i = 0; i < l.neighbours.size(); ++i) {
    e.neighbours.push_back({xz(l.neighbours[i]), static_cast<bool>(l.may_be_absent[i])});
  }
  for (std::size_t i = 0; i < l.alternatives.size(); ++i) {
    e.alternatives.push_back({xz(l.alternatives[i]), l.alternative_weights[i]});
  }
  if (l.gate_sd > 0.0) e.gate_sd = l.gate_sd;  // 0 on the wire: the core's default, no gate
  out = std::move(e);
  return {};
}

void to_msg(const PedicelExpectation& e, msgs::PedicelLayout& out) {
  out.expected = point(e.position_xz_m);
  out.expected_sd_m = e.sd_m;
  out.neighbour_sd_m = e.neighbour_sd_m;
  out.neighbours.clear();
  out.may_be_absent.clear();
  for (const auto& nb : e.neighbours) {
    out.neighbours.push_back(point(nb.position_xz_m));
    out.may_be_absent.push_back(nb.may_be_absent);
  }
  out.alternatives.clear();
  out.alternative_weights.clear();
  for (const auto& alt : e.alternatives) {
    out.alternatives.push_back(point(alt.position_xz_m));
    out.alternative_weights.push_back(alt.weight);
  }
  out.gate_sd = std::isfinite(e.gate_sd) ? e.gate_sd : 0.0;
}

void to_msg(const PedicelDetection& d, msgs::PedicelDetection& out) {
  out.outcome = wire(d.outcome);
  out.reason = d.reason;
  out.cluster = d.cluster;
  out.position = point(d.position_xz_m);
  out.width_m = d.width_m;
  out.lateral_offset_m = d.lateral_offset_m;
  out.depth_offset_m = d.depth_offset_m;
  out.angle_rad = d.angle_rad;
  out.confidence = d.confidence;
  out.num_candidates = static_cast<std::uint32_t>(d.candidates.size());
  out.candidates.clear();
  out.candidate_weights.clear();
  out.candidate_widths_m.clear();
  for (const PedicelCandidate& c : d.candidates) {
    out.candidates.push_back(point(c.position_xz_m));
    out.candidate_weights.push_back(c.weight);
    out.candidate_widths_m.push_back(c.width_m);
  }
}

std::string from_msg(const msgs::PedicelDetection& m, PedicelDetection& out) {
  if (m.outcome > msgs::PedicelDetection::INVALID_INPUT) return fmt::format("unknown outcome {}", m.outcome);
  if (m.candidate_weights.size() != m.candidates.size() || m.candidate_widths_m.size() != m.candidates.size()) {
    return fmt::format("{} candidates but {} candidate_weights and {} candidate_widths_m", m.candidates.size(),
                       m.candidate_weights.size(), m.candidate_widths_m.size());
  }
  PedicelDetection d;
  d.outcome = static_cast<PedicelOutcome>(m.outcome);
  d.reason = m.reason;
  d.cluster = m.cluster;
  d.position_xz_m = xz(m.position);
  d.width_m = m.width_m;
  d.lateral_offset_m = m.lateral_offset_m;
  d.depth_offset_m = m.depth_offset_m;
  d.angle_rad = m.angle_rad;
  d.confidence = m.confidence;
  for (std::size_t i = 0; i < m.candidates.size(); ++i) {
    PedicelCandidate c;
    c.position_xz_m = xz(m.candidates[i]);
    c.weight = m.candidate_weights[i];
    c.width_m = m.candidate_widths_m[i];
    d.candidates.push_back(c);
  }
  out = std::move(d);
  return {};
}

}  // namespace tinyline::laser_clustering
