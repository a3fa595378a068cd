// SPDX-License-Identifier: Apache-2.0
// sim_fidelity: runs the thesis's experiments on a simulated sensor and
// prints them beside the measured figures (docs/simulator_fidelity.md).
//
//   sim_fidelity --sensor sim/config/sensors/tiny_tof_8mm.yaml
//                [--measured sim/config/fidelity/thesis_measured.yaml]
//                [--json out.json] [--seed N] [--tune trap|noise|offset]
// Exit code 0 when every goal is met, 1 when one is missed, 2 on bad usage.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include <sim/fidelity.hpp>
#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

namespace cli = tinyline::cli;

using namespace tinyline::sim;

namespace {

void json(std::ostream& o, const FidelityReport& r, const ThesisFigures& m, const FidelityVerdict& v,
          const std::string& sensor) {
  o.precision(8);
  o << "{\n  \"sensor\": \"" << sensor << "\",\n  \"goals_met\": " << (v.goals_met() ? "true" : "false") << ",\n";
  o << "  \"calibration\": {\"rsen\": " << r.constants.rsen << ", \"vle_per_pulse\": " << r.constants.vle_per_pulse
    << "},\n";
  o << "  \"fits\": [";
  for (std::size_t i = 0; i < r.fits.size(); ++i) {
    const auto& f = r.fits[i];
    double mv = NAN, ms = NAN;
    for (const auto& x : m.fits)
      if (x.name == f.name) {
        mv = x.var_cm2;
        ms = x.sd_cm;
      }
    o << (i ? "," : "") << "\n    {\"name\": \"" << f.name << "\", \"var\": " << f.var_cm2 << ", \"sd\": " << f.sd_cm
      << ", \"heldout_sd\": " << f.heldout_sd_cm << ", \"measured_var\": " << mv << ", \"measured_sd\": " << ms << "}";
  }
  o << "\n  ],\n  \"table31\": [";
  for (std::size_t i = 0; i < r.table31.size(); ++i) {
    const auto& d = r.table31[i];
    const auto& md = m.table31.at(i);
    o << (i ? "," : "") << "\n    {\"truth\": " << d.truth_cm << ", \"mean\": " << d.mean_cm << ", \"sd\": " << d.sd_cm
      << ", \"n\": " << d.n << ", \"invalid\": " << d.invalid << ", \"mean_pulses\": " << d.mean_pulses
      << ", \"measured_mean\": " << md.mean_cm << ", \"measured_sd\": " << md.sd_cm << "}";
  }
  o << "\n  ],\n  \"table32\": [";
  for (std::size_t i = 0; i < r.table32.size(); ++i) {
    const auto& d = r.table32[i];
    const auto& md = m.table32.at(i);
    o << (i ? "," : "") << "\n    {\"material\": \"" << d.material << "\", \"pulses\": " << d.pulses
      << ", \"mean\": " << d.mean_cm << ", \"sd\": " << d.sd_cm << ", \"reflectance\": " << d.reflectance
      << ", \"n\": " << d.n << ", \"measured_mean\": " << md.mean_cm << ", \"measured_sd\": " << md.sd_cm
      << ", \"measured_reflectance\": " << md.reflectance << "}";
  }
  o << "\n  ],\n  \"curve\": [";
  for (std::size_t i = 0; i < r.curve.size(); ++i)
    o << (i ? "," : "") << "[" << r.curve[i].first << "," << r.curve[i].second << "]";
  o << "],\n  \"temperature_cm_per_c\": " << r.temperature_cm_per_c << ",\n  \"failures\": [";
  for (std::size_t i = 0; i < v.failures.size(); ++i) o << (i ? ", " : "") << "\"" << v.failures[i] << "\"";
  o << "]\n}\n";
}

// What --tune found, and on which figures.
void print_tune(const TuneResult& t) {
  std::printf("%s\n%s\nfit set:", t.what.c_str(), t.table.c_str());
  for (const auto& f : t.fit_set) std::printf(" %s;", f.c_str());
  std::printf("\nheld out:");
  for (const auto& f : t.held_out) std::printf(" %s;", f.c_str());
  std::printf("\nbest:");
  for (const auto& [k, v] : t.best) std::printf(" %s=%g", k.c_str(), v);
  std::printf("\nfit error %.4f, held-out error %.4f\n", t.fit_error, t.held_out_error);
}

// The simulated figures beside the thesis's, and the verdict.
void print_report(const std::string& sensor_path, const FidelityReport& r, const ThesisFigures& m,
                  const FidelityVerdict& v) {
  std::printf("sensor %s: R_sen %.4f, V_le %.5f per pulse\n\n", sensor_path.c_str(), r.constants.rsen,
              r.constants.vle_per_pulse);
  std::printf("Section 3.5 fits [cm^2, cm]        sim var   sim SD  held-out | thesis var  thesis SD\n");
  for (const auto& f : r.fits) {
    double mv = NAN, ms = NAN;
    for (const auto& x : m.fits)
      if (x.name == f.name) {
        mv = x.var_cm2;
        ms = x.sd_cm;
      }
    std::printf("  %-26s %9.3f %8.3f %8.3f | %9.3f %9.3f\n", f.name.c_str(), f.var_cm2, f.sd_cm, f.heldout_sd_cm, mv,
                ms);
  }
  std::printf("\nTable 3.1 [cm]   sim bias   sim SD  pulses | thesis bias  thesis SD  SD ratio\n");
  for (std::size_t i = 0; i < r.table31.size(); ++i) {
    const auto& d = r.table31[i];
    const auto& md = m.table31.at(i);
    std::printf("  %6.1f      %8.3f %8.3f %7.0f | %10.3f %10.3f %8.2f%s\n", d.truth_cm, d.mean_cm - d.truth_cm, d.sd_cm,
                d.mean_pulses, md.mean_cm - md.truth_cm, md.sd_cm, d.sd_cm / md.sd_cm,
                d.invalid ? " (invalid sets!)" : "");
  }
  std::printf("\nTable 3.2 [cm]     pulses  sim bias   sim SD  refl/pulse | thesis bias  thesis SD  thesis refl\n");
  for (std::size_t i = 0; i < r.table32.size(); ++i) {
    const auto& d = r.table32[i];
    const auto& md = m.table32.at(i);
    std::printf("  %-15s %5d %8.3f %8.3f %10.3f | %10.3f %10.3f %10.3f\n", d.material.c_str(), d.pulses,
                d.mean_cm - 30.0, d.sd_cm, d.reflectance, md.mean_cm - 30.0, md.sd_cm, md.reflectance);
  }
  std::printf("\nTemperature (3.3.4): %.3f cm per degC during warm-up\n", r.temperature_cm_per_c);
  std::printf("\n%s\n", v.goals_met() ? "All goals met." : "Goals missed:");
  for (const auto& f : v.failures) std::printf("  - %s\n", f.c_str());
}
}  // namespace

int main(int argc, char** argv) {
  std::string sensor_path,
      measured_path = std::string(TINYLINE_SIM_SOURCE_DIR) + "/config/fidelity/thesis_measured.yaml";
  std::string json_path, tune;
  FidelityOptions opt;
  cli::App app{
      "Runs the thesis's experiments on a simulated sensor and prints them beside the measured figures "
      "(docs/simulator_fidelity.md). Exit code 0 when every goal is met, 1 when one is missed, 2 on bad usage.",
      "sim_fidelity"};
  app.add_option("--sensor", sensor_path, "sensor YAML (sim/config/sensors/...)")->required();
  app.add_option("--measured", measured_path, "the thesis's measured figures (YAML)")->capture_default_str();
  app.add_option("--json", json_path, "also write the report as JSON here");
  app.add_option("--seed", opt.seed_offset, "offset of every experiment's seed")
      ->check(cli::non_negative())
      ->capture_default_str();
  app.add_option("--tune", tune, "tune one group of the sensor's constants instead")
      ->check(cli::one_of({"trap", "noise", "offset"}));
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  if (!json_path.empty() && !tinyline::files::output_allowed(
                                "sim_fidelity", json_path, {.inputs = {sensor_path, measured_path}, .what = "report"}))
    return 1;
  try {
    const SensorParams p = load_sensor_params(sensor_path);
    const ThesisFigures m = load_thesis_figures(measured_path);
    if (!tune.empty()) {
      const TuneResult t = tune == "trap"    ? tune_trap(p, m, opt)
                           : tune == "noise" ? tune_noise(p, m, opt)
                                             : tune_offset(p, m, opt);
      print_tune(t);
      return 0;
    }
    const FidelityReport r = run_fidelity(p, opt);
    const FidelityVerdict v = judge(r, m);
    print_report(sensor_path, r, m, v);
    if (!json_path.empty()) {
      tinyline::files::AtomicStream o(json_path);
      json(o, r, m, v, sensor_path);
      o.commit();
    }
    return v.goals_met() ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "sim_fidelity: " << e.what() << "\n";
    return 1;
  }
}
