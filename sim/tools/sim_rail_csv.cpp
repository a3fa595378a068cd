// SPDX-License-Identifier: Apache-2.0
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
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <optional>
#include <random>
#include <string>

#include <sim/rail.hpp>
#include <sim/sensor_params.hpp>
#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

namespace cli = tinyline::cli;

namespace {

namespace sim = tinyline::sim;

struct Options {
  std::string sensor, out, material = "white_paper";
  double from = 0.05, to = 2.0, step = 0.05;
  int visits = 2, sets = 3, pixel_step = 1;
  unsigned seed = 7;
  bool constants = false;
};

/// The command line; an exit code when the program should stop (help, bad options).
std::optional<int> parse(int argc, char** argv, Options& o) {
  cli::App app{
      "Calibration data from the simulated sensor on the simulated calibration rail, as the CSV "
      "`tinyline calib fit` reads; or (--constants) the leakage per pulse and Rsen measured as the thesis did.",
      "sim_rail_csv"};
  app.add_option("--sensor", o.sensor, "sensor YAML")->required();
  app.add_option("-o", o.out, "CSV file to write (required unless --constants)");
  app.add_option("--from", o.from, "nearest target distance [m]")->check(cli::positive())->capture_default_str();
  app.add_option("--to", o.to, "farthest target distance [m]")->check(cli::positive())->capture_default_str();
  app.add_option("--step", o.step, "distance step [m]")->check(cli::positive())->capture_default_str();
  app.add_option("--visits", o.visits, "visits of each distance")->check(cli::range(1, 1000))->capture_default_str();
  app.add_option("--sets", o.sets, "sets per visit")->check(cli::range(1, 1000))->capture_default_str();
  app.add_option("--pixel-step", o.pixel_step, "every N-th effective pixel")
      ->check(cli::range(1, 256))
      ->capture_default_str();
  app.add_option("--material", o.material, "target material")->capture_default_str();
  app.add_option("--seed", o.seed, "seed of the visiting order")->check(cli::non_negative())->capture_default_str();
  app.add_flag("--constants", o.constants, "measure the leakage per pulse and Rsen instead (laser off)");
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return rc;
  if (o.out.empty() && !o.constants) {
    std::cerr << "sim_rail_csv: -o OUT.csv is required (or --constants)\nRun with --help for more information.\n";
    return 2;
  }
  if (!(o.to >= o.from)) {
    std::cerr << "sim_rail_csv: --to (" << o.to << ") must not be below --from (" << o.from << ")\n";
    return 2;
  }
  return std::nullopt;
}

/// Leakage per pulse Vle: in the dark b = Vle(p) (and a = Vle / Rsen), so b
/// regressed on the pulses through 0 (thesis 3.3.3).
double leakage_per_pulse(const sim::SensorParams& params, const sim::CalibrationRail& rail) {
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
  return spb / spp;
}

/// Sensitivity ratio Rsen: under even ambient light with the laser off both
/// gates hold the same charge, so b / a = Rsen (thesis 3.3.3).
double sensitivity_ratio(const sim::SensorParams& params, const sim::RailParams& rp) {
  sim::MeasureOptions off;
  off.laser_on = false;
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
  return sb / sa;
}

/// Every distance `visits` times, in an order shuffled with `seed`.
std::vector<double> visiting_order(const Options& o) {
  std::vector<double> distances;
  for (int v = 0; v < o.visits; ++v) {
    for (double d = o.from; d <= o.to + 1e-9; d += o.step) distances.push_back(d);
  }
  std::mt19937 rng(o.seed);
  std::shuffle(distances.begin(), distances.end(), rng);
  return distances;
}

/// Every `pixel_step`-th effective pixel.
std::vector<int> sampled_pixels(const sim::SensorParams& params, int pixel_step) {
  std::vector<int> pixels;
  const int dark = params.lens.dark_pixels;
  for (int p = dark; p < params.lens.pixels - dark; p += pixel_step) pixels.push_back(p);
  return pixels;
}

struct Session {
  std::vector<sim::CalibrationRow> rows;
  double t_end_s = 0.0;  ///< sensor time at the end
};

/// `sets` sets at each distance in turn, from power-on (the warm-up is in the
/// data), a set every 2 s at least. As sim::run_sweep, but every read-out of
/// a set carries the set's time: the calibration tool groups the read-outs of
/// one frame by t_s (to pick the one the driver uses), and the driver sees
/// them as one set.
Session record(sim::CalibrationRail r, const sim::SensorParams& params, const std::vector<double>& distances, int sets,
               const std::vector<int>& pixels) {
  Session s;
  std::uint64_t index = 0;
  for (double d : distances) {
    r.set_target_distance(d);
    for (int k = 0; k < sets; ++k) {
      const sim::SensorSet set = r.measure(s.t_end_s, params.acquisition.raw_pulses, index++);
      auto part = sim::calibration_rows(set, r.world(), pixels);
      for (auto& row : part) row.t_s = set.t_start_s;
      s.rows.insert(s.rows.end(), std::make_move_iterator(part.begin()), std::make_move_iterator(part.end()));
      s.t_end_s += std::max(2.0, set.t_end_s - set.t_start_s);
    }
  }
  return s;
}

void run(const Options& o) {
  const sim::SensorParams params = sim::load_sensor_params(o.sensor);
  sim::RailParams rp;
  rp.material = o.material;
  rp.target_width_m = 4.0;  // wide enough for the 3.6 mm lens's 71 deg at 2 m
  const sim::CalibrationRail rail(params, rp);
  if (o.constants) {
    const double vle = leakage_per_pulse(params, rail);
    std::printf("--leakage 0,%.6g --rsen-value %.6g\n", vle, sensitivity_ratio(params, rp));
    return;
  }
  const std::vector<double> distances = visiting_order(o);
  const std::vector<int> pixels = sampled_pixels(params, o.pixel_step);
  const Session session = record(rail, params, distances, o.sets, pixels);
  tinyline::files::AtomicStream f(o.out);
  sim::write_calibration_csv(f, session.rows, /*with_material=*/true);
  f.commit();
  std::cout << "wrote " << session.rows.size() << " rows (" << distances.size() << " visits x " << o.sets << " sets, "
            << pixels.size() << " pixels, sensor time 0-" << session.t_end_s << " s) to " << o.out << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const auto rc = parse(argc, argv, o)) return *rc;
  if (!o.out.empty() &&
      !tinyline::files::output_allowed("sim_rail_csv", o.out, {.inputs = {o.sensor}, .what = "data file"}))
    return 1;
  try {
    run(o);
  } catch (const std::exception& e) {
    std::cerr << "sim_rail_csv: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
