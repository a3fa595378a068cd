// SPDX-License-Identifier: Apache-2.0
// Five seeds per injected effect: how reliably the residual loop names it and
// how close the held-out error gets to the effect-free twin's. Stays disabled:
// 36 s on the shared two cores, and it does not hold (5 of 5 fails for the
// null case, seed 5 naming a bank contrast; time drift, seed 5 naming the
// slowest lagged temperature; the capacitor nonlinearity, 3 of 5), which
// docs/calibration.md reports; the figures there come from
//   build/tiny_laser_calibration/tiny_laser_calibration_sweep_test --gtest_also_run_disabled_tests
#include <cmath>
#include <cstdio>
#include <functional>

#include <gtest/gtest.h>

#include <tiny_laser_calibration/discovery.hpp>

#include "synthetic_sensor.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;

TEST(CalibrationSweep, DISABLED_FiveSeedsPerEffect) {
  struct Case {
    const char* name;
    const char* expected;
    std::function<void(tt::SyntheticSensor&, tt::RailPlan&)> setup;
  };
  const std::vector<Case> cases = {
      {"none", "", [](auto& s, auto&) { s.effects.supply_column = true; }},
      {"material bias (Table 3.2)", "albedo",
       [](auto& s, auto& p) {
         s.effects.material_bias = true;
         p.materials = tt::table_3_2_materials();
         p.frames_per_visit = 1;
         p.pixels.clear();
         for (int px = 8; px < 264; px += 16) p.pixels.push_back(px);
       }},
      {"supply voltage", "supply_v", [](auto& s, auto&) { s.effects.supply_voltage = true; }},
      {"time drift", "t_s",
       [](auto& s, auto& p) {
         s.effects.time_drift = true;
         s.effects.time_drift_m_per_ks = 0.02;
         p.passes = 3;
       }},
      {"capacitor nonlinearity", "charge",
       [](auto& s, auto&) {
         s.effects.capacitor_nonlinearity = true;
         s.effects.nonlinearity_eta = 0.15;
       }},
  };
  std::printf("\n| effect | seed | named | held-out before [cm] | after [cm] | floor [cm] | after / floor |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (const auto& c : cases) {
    int hits = 0;
    for (int seed = 1; seed <= 5; ++seed) {
      tt::SyntheticSensor s;
      s.seed = static_cast<std::uint64_t>(seed);
      auto plan = tt::default_rail();
      plan.seed = static_cast<std::uint64_t>(100 + seed);
      c.setup(s, plan);
      const auto r = cal::discover_effects(tt::simulate_rail(s, plan));
      tt::SyntheticSensor clean = s;
      clean.effects = {};
      clean.effects.supply_column = s.effects.supply_voltage || s.effects.supply_column;
      const auto floor = cal::discover_effects(tt::simulate_rail(clean, plan));
      ASSERT_TRUE(r.status.ok() && floor.status.ok()) << r.status.message << floor.status.message;
      std::string named;
      for (const auto& e : r.effects) named += e.covariate + "/" + std::string(tl::to_string(e.form)) + " ";
      const bool hit = std::string(c.expected).empty()
                           ? r.effects.empty()
                           : (!r.effects.empty() && r.effects.front().covariate == c.expected);
      hits += hit ? 1 : 0;
      std::printf("| %s | %d | %s | %.3f | %.3f | %.3f | %.3f |\n", c.name, seed, named.empty() ? "-" : named.c_str(),
                  100 * r.rmse_before_m, 100 * r.rmse_after_m, 100 * floor.rmse_before_m,
                  r.rmse_after_m / floor.rmse_before_m);
      EXPECT_LT(r.rmse_after_m, 1.2 * floor.rmse_before_m) << c.name << " seed " << seed;
    }
    EXPECT_EQ(hits, 5) << c.name;
  }
}
