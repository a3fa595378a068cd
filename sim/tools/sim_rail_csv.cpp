// sim_rail_csv: calibration data from the simulated sensor on the simulated
// calibration rail (sim/rail.hpp), as the CSV `tinyline calib fit` reads.
// Used to make the default calibration the driver ships for the simulated
// sensor (tiny_laser_driver/config/calibration/README.md has the commands).
//
//   sim_rail_csv --sensor sim/config/sensors/tiny_tof_8mm.yaml -o rail.csv
//                [--from 0.05] [--to 2.0] [--step 0.05] [--visits 2] [--sets 3]
//                [--pixel-step 1] [--material white_paper] [--seed 7]
//   sim_rail_csv --sensor SENSOR.yaml --constants
//
// --constants measures what the thesis measured before fitting (3.3.3): the
// leakage per pulse with the laser off in the dark, and the sensitivity ratio
// Rsen under even ambient light (laser off); it prints them as the options
// of `tinyline calib fit` (--leakage 0,VLE --rsen-value RSEN).
//
// Each distance is visited `visits` times in a shuffled order while the sensor
// warms up from power-on (a set every 2 s of sensor time), so temperature and
// distance are not confounded; every read-out of every `pixel-step`-th
// effective pixel that sees the target is a row.
#include <algorithm>
#include <vector>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <random>
#include <string>

#include <sim/rail.hpp>
#include <sim/sensor_params.hpp>
#include <tinyline/common/cli.hpp>

int main(int argc, char** argv) {
  std::string sensor, out, material = "white_paper";
  double from = 0.05, to = 2.0, step = 0.05;
  int visits = 2, sets = 3, pixel_step = 1;
  unsigned seed = 7;
  bool constants = false;
  CLI::App app{"Calibration data from the simulated sensor on the simulated calibration rail, as the CSV "
               "`tinyline calib fit` reads; or (--constants) the leakage per pulse and Rsen measured as the thesis did.",
               "sim_rail_csv"};
  app.add_option("--sensor", sensor, "sensor YAML")->required();
  app.add_option("-o", out, "CSV file to write (required unless --constants)");
  app.add_option("--from", from, "nearest target distance [m]")->check(tinyline::common::kPositive)->capture_default_str();
  app.add_option("--to", to, "farthest target distance [m]")->check(tinyline::common::kPositive)->capture_default_str();
  app.add_option("--step", step, "distance step [m]")->check(tinyline::common::kPositive)->capture_default_str();
  app.add_option("--visits", visits, "visits of each distance")->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--sets", sets, "sets per visit")->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--pixel-step", pixel_step, "every N-th effective pixel")->check(CLI::Range(1, 256))->capture_default_str();
  app.add_option("--material", material, "target material")->capture_default_str();
  app.add_option("--seed", seed, "seed of the visiting order")->check(tinyline::common::kNonNegative)->capture_default_str();
  app.add_flag("--constants", constants, "measure the leakage per pulse and Rsen instead (laser off)");
  if (const auto rc = tinyline::common::parse_command_line(app, argc, argv)) return *rc;
  if (out.empty() && !constants) {
    std::cerr << "sim_rail_csv: -o OUT.csv is required (or --constants)\nRun with --help for more information.\n";
    return 2;
  }
  if (!(to >= from)) {
    std::cerr << "sim_rail_csv: --to (" << to << ") must not be below --from (" << from << ")\n";
    return 2;
  }
  try {
    namespace sim = tinyline::sim;
    const sim::SensorParams params = sim::load_sensor_params(sensor);
    sim::RailParams rp;
    rp.material = material;
    rp.target_width_m = 4.0;  // wide enough for the 3.6 mm lens's 71 deg at 2 m
    const sim::CalibrationRail rail(params, rp);
    if (constants) {
      // Dark: b = Vle(p) (and a = Vle / Rsen); regress on the pulses through 0.
      sim::MeasureOptions off;
      off.laser_on = false;
      const std::vector<int> schedule{100, 400, 700};
      double spb = 0.0, spp = 0.0;
      for (int k = 0; k < 20; ++k) {
        const sim::SensorSet s = rail.measure(3600.0, schedule, 100000 + static_cast<std::uint64_t>(k), off);
        for (const auto& r : s.readouts) {
          for (int p = params.lens.dark_pixels; p < params.lens.pixels - params.lens.dark_pixels; ++p) {
            spb += r.pulses * r.b[static_cast<std::size_t>(p)];
            spp += static_cast<double>(r.pulses) * r.pulses;
          }
        }
      }
      const double vle = spb / spp;
      // Even ambient light, laser off: the same charge in both gates, so b / a = Rsen.
      sim::SensorParams lit = params;
      lit.environment.ambient_charge_per_pulse = 0.3;
      const sim::CalibrationRail lamp(lit, rp);
      double sa = 0.0, sb = 0.0;
      for (int k = 0; k < 20; ++k) {
        const sim::SensorSet s = lamp.measure(3600.0, std::vector<int>{400}, 200000 + static_cast<std::uint64_t>(k), off);
        for (int p = params.lens.dark_pixels; p < params.lens.pixels - params.lens.dark_pixels; ++p) {
          sa += s.readouts[0].a[static_cast<std::size_t>(p)];
          sb += s.readouts[0].b[static_cast<std::size_t>(p)];
        }
      }
      std::printf("--leakage 0,%.6g --rsen-value %.6g\n", vle, sb / sa);
      return 0;
    }
    std::vector<double> distances;
    for (int v = 0; v < visits; ++v) {
      for (double d = from; d <= to + 1e-9; d += step) distances.push_back(d);
    }
    std::mt19937 rng(seed);
    std::shuffle(distances.begin(), distances.end(), rng);
    std::vector<int> pixels;
    const int dark = params.lens.dark_pixels;
    for (int p = dark; p < params.lens.pixels - dark; p += pixel_step) pixels.push_back(p);
    // As sim::run_sweep, but every read-out of a set carries the set's time:
    // the calibration tool groups the read-outs of one frame by t_s (to pick
    // the one the driver uses), and the driver sees them as one set.
    sim::CalibrationRail r = rail;
    std::vector<sim::CalibrationRow> rows;
    double t = 0.0;  // power-on: the warm-up is in the data
    std::uint64_t index = 0;
    for (double d : distances) {
      r.set_target_distance(d);
      for (int k = 0; k < sets; ++k) {
        const sim::SensorSet set = r.measure(t, params.acquisition.raw_pulses, index++);
        auto part = sim::calibration_rows(set, r.world(), pixels);
        for (auto& row : part) row.t_s = set.t_start_s;
        rows.insert(rows.end(), std::make_move_iterator(part.begin()), std::make_move_iterator(part.end()));
        t += std::max(2.0, set.t_end_s - set.t_start_s);
      }
    }
    std::ofstream f(out);
    if (!f) throw std::runtime_error("cannot write " + out);
    sim::write_calibration_csv(f, rows, /*with_material=*/true);
    std::cout << "wrote " << rows.size() << " rows (" << distances.size() << " visits x " << sets << " sets, "
              << pixels.size() << " pixels, sensor time 0-" << t << " s) to " << out << "\n";
  } catch (const std::exception& e) {
    std::cerr << "sim_rail_csv: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
