// SPDX-License-Identifier: Apache-2.0
// The residual loop against the simulator, one undeclared effect at a time:
// the cases the tests hold (one seed each) and the sweep measures
// (calibration_discovery_sweep, many seeds). Each case is the declared-physics
// sensor (sim/config/sensors/tiny_tof_declared.yaml, read-out offsets and
// leakage spread off) plus one effect, on a rail that shows it; its twin is
// the same sensor and rail without the effect (the noise floor).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <sim/sensor_params.hpp>
#include <tiny_laser_calibration/discovery.hpp>

#include "sim_rail_session.hpp"

namespace tinyline::tiny_laser_calibration::testing {

struct DiscoveryCase {
  std::string name;
  std::string what;                   ///< the effect and its size, for the docs
  std::vector<std::string> expected;  ///< the first effect named is one of these covariates (empty: none)
  bool on_charges = false;            ///< ... in a form that acts on the charges
  std::function<void(tinyline::sim::SensorParams&)> inject;
  std::function<void(RailPlan&)> plan;                       ///< changes to the default rail
  std::function<void(tinyline::sim::SensorParams&)> sensor;  ///< changes to both twins (the sensor it needs)
  bool rsen_fixed = false;             ///< one Rsen for every pixel (the published firmware's model)
  bool twin_must_be_null = true;       ///< the effect-free twin names nothing
  double min_before_over_floor = 1.2;  ///< the effect matters: held-out error before / floor
  /// Set: both twins also record a second warm-up (a `session` column; the first
  /// session is 0), on the sensor changed by this (e.g. another day's ambient).
  std::function<void(tinyline::sim::SensorParams&)> second_session{};
};

/// Every case (the first is the null case: nothing injected).
const std::vector<DiscoveryCase>& discovery_cases();
const DiscoveryCase& discovery_case(const std::string& name);

/// The declared-physics sensor the cases start from.
tinyline::sim::SensorParams declared_sensor();

struct CaseOutcome {
  DiscoveryResult result;  ///< with the effect
  DiscoveryResult twin;    ///< without it
  double floor_m = 0.0;    ///< the twin's held-out error of the declared model
  bool named = false;      ///< the first effect is one of the expected (none expected: nothing named)
  [[nodiscard]] std::string names() const;
};

/// "covariate/form " of each effect named, "(none)" when none.
std::string effect_names(const DiscoveryResult& r);

/// Runs one case at one seed (the rail's visit order and noise, the sensor's per-pixel constants).
CaseOutcome run_case(const DiscoveryCase& c, std::uint64_t seed);

}  // namespace tinyline::tiny_laser_calibration::testing
