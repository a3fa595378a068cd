// SPDX-License-Identifier: Apache-2.0
// Thesis section 3.5 on the simulator's data: regressions of distance on the
// charge ratio of the two central pixels (135, 136) of the thesis-fidelity
// 8 mm sensor (sim/config/sensors/tiny_tof_8mm.yaml) on the simulated rail,
// white paper, 5-200 cm, warm: fixed discharge (40 %, 20 %: one read-out per
// set, its pulse count chosen per distance) and multi-discharge (the five raw
// read-outs 20-700 pulses, K_i = 1). Rsen and Vle measured apart first, as the
// thesis did. The table printed is the one in docs/calibration.md beside the
// thesis's figures (sim/config/fidelity/thesis_measured.yaml calibration_fits_cm).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include <sim/rail.hpp>
#include <sim/sensor_params.hpp>
#include <tiny_laser_calibration/fit.hpp>

#include "section35_figures.hpp"

#include "sim_rail_session.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace sim = tinyline::sim;
namespace tt = tinyline::tiny_laser_calibration::testing;

namespace {

sim::SensorParams sensor() {
  return sim::load_sensor_params(std::string(TINYLINE_SOURCE_DIR) + "/sim/config/sensors/tiny_tof_8mm.yaml");
}

cal::CalibrationDataset rail(std::optional<double> discharge, std::uint64_t first_index) {
  sim::RailParams rp;
  rp.target_width_m = 4.0;
  const sim::CalibrationRail r(sensor(), rp);
  sim::RailSweep sweep;
  for (int k = 1; k <= 40; ++k) sweep.distances_m.push_back(0.05 * k);
  sweep.sets_per_distance = 10;
  sweep.discharge_fraction = discharge;
  sweep.first_index = first_index;
  cal::CalibrationDataset data;
  data.source = "simulated rail";
  for (const auto& row : sim::run_sweep(r, sweep)) {
    tl::Readout ro;
    ro.a = row.a;
    ro.b = row.b;
    ro.pulses = row.pulses;
    ro.temperature_c = row.temperature_c;
    ro.pixel = row.pixel;
    ro.t_s = row.t_s;
    data.add(std::move(ro), row.distance_m);
  }
  return data;
}

cal::DeclaredFitParams fit_params(int degree) {
  static const tt::RailConstants c = tt::measure_rail_constants(sensor());
  cal::DeclaredFitParams p;
  p.degree = degree;
  p.sensitivity_ratio_mode = cal::SensitivityRatioMode::kFixed;
  p.sensitivity_ratio = c.sensitivity_ratio;
  p.fit_leakage = false;
  p.leakage_per_pulse = c.leakage_per_pulse;
  p.fit_temperature = false;                  // warm: the thesis's 3.5 data hold no warm-up
  p.selection = cal::ReadoutSelection::kAll;  // every valid read-out of the data set (Eq. 3.20, K = 1)
  return p;
}

}  // namespace

TEST(CalibrationSimSection35, FitDegreeAndDischargeOnTheSimulatedSensor) {
  const auto d40 = rail(0.4, 1000000);
  const auto d20 = rail(0.2, 2000000);
  const auto multi = rail(std::nullopt, 3000000);
  const auto [lin, p3, p6, p6_20, p6_multi] = tt::section35_table(d40, d20, multi, fit_params);
  // The simulated read-out noise (about 4.7 cm at 40 % discharge, five times the
  // thesis's 0.86 cm) dominates every polynomial fit, so only the orderings that
  // survive it are held: a line is far off, the degree-6 fit is no worse than
  // degree 3, and half the charge (20 %) is noisier than 40 %. Multi-discharge vs
  // fixed 40 % is printed, not held (a few percent apart here).
  EXPECT_GT(lin.sd_cm, 1.3 * p6.sd_cm);
  EXPECT_GT(lin.heldout_sd_cm, 1.3 * p6.heldout_sd_cm);
  EXPECT_GE(p3.sd_cm, p6.sd_cm);
  EXPECT_GT(p6_20.sd_cm, p6.sd_cm);
  EXPECT_GT(p6_20.heldout_sd_cm, p6.heldout_sd_cm);
}
