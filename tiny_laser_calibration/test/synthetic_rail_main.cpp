// SPDX-License-Identifier: Apache-2.0
// calibration_synthetic_rail: writes a calibration CSV from the documented
// two-capacitor model of the calibration tests (synthetic_sensor.hpp), with
// chosen undeclared effects, for docs/calibration.md. Not installed.
//
//   calibration_synthetic_rail -o rail.csv [--effect material|supply|time|nonlin|pixel]...
//                              [--supply-column] [--materials white|table32] [--passes N] [--pixel-step N]
//                              [--seed N]
#include <cstdio>
#include <string>
#include <vector>

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

#include "synthetic_sensor.hpp"

namespace cli = tinyline::cli;

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;

int main(int argc, char** argv) {
  tt::SyntheticSensor s;
  auto plan = tt::default_rail();
  std::string out, materials = "white";
  int pixel_step = 4;
  std::vector<std::string> effects;
  cli::App app{
      "Writes a calibration CSV from the two-capacitor model of the calibration tests, with chosen "
      "undeclared effects (docs/calibration.md).",
      "calibration_synthetic_rail"};
  app.add_option("-o", out, "CSV file to write")->required();
  app.add_option("--effect", effects, "an undeclared effect (repeatable)")
      ->check(cli::one_of({"material", "supply", "time", "nonlin", "pixel"}));
  app.add_flag("--supply-column", s.effects.supply_column, "also write the supply voltage as a column");
  app.add_option("--materials", materials, "target materials")
      ->check(cli::one_of({"white", "table32"}))
      ->capture_default_str();
  app.add_option("--passes", plan.passes, "visits of each distance")->check(cli::range(1, 1000))->capture_default_str();
  app.add_option("--pixel-step", pixel_step, "every N-th effective pixel")
      ->check(cli::range(1, 256))
      ->capture_default_str();
  app.add_option("--seed", plan.seed, "seed of the visiting order and the noise")
      ->check(cli::non_negative())
      ->capture_default_str();
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  if (!tinyline::files::output_allowed("calibration_synthetic_rail", out, tinyline::files::named("data file")))
    return 1;
  for (const std::string& e : effects) {
    if (e == "material") {
      s.effects.material_bias = true;
    } else if (e == "supply") {
      s.effects.supply_voltage = true;
    } else if (e == "time") {
      s.effects.time_drift = true;
      s.effects.time_drift_m_per_ks = 0.02;
    } else if (e == "nonlin") {
      s.effects.capacitor_nonlinearity = true;
      s.effects.nonlinearity_eta = 0.15;
    } else {
      s.effects.pixel_pattern = true;
    }
  }
  if (materials == "table32") {
    plan.materials = tt::table_3_2_materials();
    plan.frames_per_visit = 1;
  }
  plan.pixels.clear();
  for (int px = 8; px < 264; px += pixel_step) plan.pixels.push_back(px);
  const auto data = tt::simulate_rail(s, plan);
  cal::write_calibration_csv(data, out);
  std::printf("wrote %zu rows to %s\n", data.size(), out.c_str());
  return 0;
}
