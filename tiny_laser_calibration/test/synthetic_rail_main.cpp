// calibration_synthetic_rail: writes a calibration CSV from the documented
// two-capacitor model of the calibration tests (synthetic_sensor.hpp), with
// chosen undeclared effects. For docs/calibration.md until the simulator's
// rail feeds `tinyline calib collect`; not installed.
//
//   calibration_synthetic_rail -o rail.csv [--effect material|supply|time|nonlin|pixel]...
//                              [--materials white|table32] [--passes N] [--pixel-step N] [--seed N]
#include <cstdio>
#include <cstdlib>
#include <string>

#include "synthetic_sensor.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;

int main(int argc, char** argv) {
  tt::SyntheticSensor s;
  auto plan = tt::default_rail();
  std::string out;
  int pixel_step = 4;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "-o") {
      out = next();
    } else if (a == "--effect") {
      const std::string e = next();
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
      } else if (e == "pixel") {
        s.effects.pixel_pattern = true;
      } else {
        std::fprintf(stderr, "unknown effect '%s'\n", e.c_str());
        return 2;
      }
    } else if (a == "--supply-column") {
      s.effects.supply_column = true;
    } else if (a == "--materials") {
      const std::string m = next();
      if (m == "table32") {
        plan.materials = tt::table_3_2_materials();
        plan.frames_per_visit = 1;
      } else if (m != "white") {
        std::fprintf(stderr, "--materials: white or table32\n");
        return 2;
      }
    } else if (a == "--passes") {
      plan.passes = std::atoi(next().c_str());
    } else if (a == "--pixel-step") {
      pixel_step = std::atoi(next().c_str());
    } else if (a == "--seed") {
      plan.seed = static_cast<std::uint64_t>(std::atoll(next().c_str()));
    } else {
      std::fprintf(stderr, "unknown argument '%s'\n", a.c_str());
      return 2;
    }
  }
  if (out.empty() || pixel_step < 1) {
    std::fprintf(stderr, "usage: calibration_synthetic_rail -o rail.csv [--effect E]... [--materials white|table32]\n");
    return 2;
  }
  plan.pixels.clear();
  for (int px = 8; px < 264; px += pixel_step) plan.pixels.push_back(px);
  const auto data = tt::simulate_rail(s, plan);
  cal::write_calibration_csv(data, out);
  std::printf("wrote %zu rows to %s\n", data.size(), out.c_str());
  return 0;
}
