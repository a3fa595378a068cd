// SPDX-License-Identifier: Apache-2.0
// calibration_sim_rail_bag: records a calibration session on the simulated
// rail as a bag (virtual sensor + recorder on sim time), the input of
// `tinyline calib collect` in docs/calibration.md. Not installed.
//
//   calibration_sim_rail_bag --scene sim/config/scenes/calibration_rail.yaml -o rail.mcap
//       [--from 0.15] [--to 2.0] [--step 0.05] [--visits 2] [--sets 3] [--power-on-age 0] [--seed 7]
#include <algorithm>
#include <iostream>
#include <random>
#include <string>

#include "sim_rail_session.hpp"

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

namespace cli = tinyline::cli;

int main(int argc, char** argv) {
  namespace tt = tinyline::tiny_laser_calibration::testing;
  tt::SimRailSession s;
  double from = 0.15, to = 2.0, step = 0.05;
  int visits = 2;
  unsigned seed = 7;
  cli::App app{
      "Records a calibration session on the simulated rail as a bag (virtual sensor + recorder on sim "
      "time), the input of `tinyline calib collect` (docs/calibration.md).",
      "calibration_sim_rail_bag"};
  app.add_option("--scene", s.scene, "rail scene YAML")->required();
  app.add_option("-o", s.bag_path, "bag to write (MCAP)")->required();
  app.add_option("--from", from, "nearest target distance [m]")->check(cli::positive())->capture_default_str();
  app.add_option("--to", to, "farthest target distance [m]")->check(cli::positive())->capture_default_str();
  app.add_option("--step", step, "distance step [m]")->check(cli::positive())->capture_default_str();
  app.add_option("--visits", visits, "visits of each distance")->check(cli::range(1, 1000))->capture_default_str();
  app.add_option("--sets", s.sets_per_distance, "sets per visit")->check(cli::range(1, 1000))->capture_default_str();
  app.add_option("--power-on-age", s.power_on_age_s, "sensor time at the start [s] (0: the warm-up is in the data)")
      ->check(cli::non_negative())
      ->capture_default_str();
  app.add_option("--seed", seed, "seed of the visiting order")->check(cli::non_negative())->capture_default_str();
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  if (!tinyline::files::output_allowed("calibration_sim_rail_bag", s.bag_path, {.inputs = {s.scene}, .what = "bag"}))
    return 1;
  if (!(to >= from)) {
    std::cerr << "calibration_sim_rail_bag: --to (" << to << ") must not be below --from (" << from << ")\n";
    return 2;
  }
  for (int v = 0; v < visits; ++v) {
    for (double d = from; d <= to + 1e-9; d += step) s.distances_m.push_back(d);
  }
  std::mt19937 rng(seed);
  std::shuffle(s.distances_m.begin(), s.distances_m.end(), rng);
  const auto r = tt::record_sim_rail_session(s);
  if (!r.error.empty()) {
    std::cerr << "calibration_sim_rail_bag: " << r.error << "\n";
    return 1;
  }
  std::cout << "wrote " << s.bag_path << ": " << r.raw_scans << " raw scans, " << r.truths << " truths ("
            << s.distances_m.size() << " rail positions x " << s.sets_per_distance << " sets), " << r.dropped
            << " dropped\n";
  return r.dropped == 0 ? 0 : 1;
}
