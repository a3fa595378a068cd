// tomato_eval: scores the tomato pipeline on seeded simulated trusses
// (docs/tomato_reasoning.md). Each truss is rendered once; every variant runs
// on the same cloud.
//
//   tomato_eval --classes A,B,C --seeds 1-100 --out DIR
//               [--variant NAME]... [--set key=value]... [--kappa-sweep k1,k2,...]
//               [--fit-kappa] [--views 1|2] [--verify]
//
// --fit-kappa fits the pedicel distribution's vMF kernel concentration
// (force.kernel_kappa) on the given seeds: the kappa of a log grid whose HPD50
// region holds the true pedicel closest to 50 % of the time (run it on
// fitting seeds, never on the seeds you report).
//
// Writes DIR/<variant>_tomatoes.csv (one row per true tomato) and
// DIR/<variant>_summary.json (per class and overall), and prints a table.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/scoring.hpp"
#include "tomato_reasoning/eval/variants.hpp"
#include "tomato_reasoning/pipeline.hpp"
#include "tomato_reasoning/eval/verification.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep))
    if (!item.empty()) out.push_back(item);
  return out;
}

std::vector<std::uint64_t> parse_seeds(const std::string& s) {
  std::vector<std::uint64_t> out;
  for (const auto& part : split(s, ',')) {
    const auto dash = part.find('-');
    if (dash == std::string::npos) {
      out.push_back(std::stoull(part));
    } else {
      const std::uint64_t a = std::stoull(part.substr(0, dash)), b = std::stoull(part.substr(dash + 1));
      if (b < a) throw std::invalid_argument("seed range '" + part + "' runs backwards");
      for (std::uint64_t k = a; k <= b; ++k) out.push_back(k);
    }
  }
  return out;
}

void usage() {
  std::puts(
      "usage: tomato_eval --classes A,B,C --seeds 1-100 --out DIR [--variant NAME]... [--set key=value]...\n"
      "                   [--kappa-sweep k1,k2,...] [--fit-kappa] [--views 1|2] [--pose-noise M,DEG] [--verify]\n"
      "                   [--verify-set key=value]... [--quiet]\n"
      "--fit-kappa: fit force.kernel_kappa on these seeds (HPD50 coverage closest to 50 %, log grid 2..1000),\n"
      "          written to DIR/kappa_fit.csv\n"
      "--verify: laser verification of every detected tomato's pick (first variant), as recognised and with a\n"
      "          random offset < 5 cm (Table 4.3), written to DIR/verification.csv\n"
      "--verify-set key=value: the verification's options (pulses=10,20,50,120,300 expectation_sd_m=0.015\n"
      "          max_move_m=0.05 max_turn_deg=60), e.g. to rerun a before/after row\n"
      "variants: ");
  for (const auto& v : eval::variant_names()) std::printf("  %s\n", v.c_str());
  std::puts("keys for --set:");
  for (const auto& k : eval::param_keys()) std::printf("  %s\n", k.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> classes{"A", "B", "C"};
  std::vector<std::uint64_t> seeds;
  std::string out_dir;
  std::vector<std::string> variants;
  std::vector<std::pair<std::string, std::string>> sets;
  std::vector<double> kappas;
  bool quiet = false;
  bool verify = false;
  bool fit_kappa = false;
  std::vector<std::pair<std::string, std::string>> verify_sets;
  eval::ScenarioOptions scenario;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--classes") classes = split(next(), ',');
      else if (a == "--seeds") seeds = parse_seeds(next());
      else if (a == "--out") out_dir = next();
      else if (a == "--variant") variants.push_back(next());
      else if (a == "--set") {
        const std::string kv = next();
        const auto eq = kv.find('=');
        if (eq == std::string::npos) throw std::invalid_argument("--set wants key=value, got '" + kv + "'");
        sets.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
      } else if (a == "--kappa-sweep") {
        for (const auto& k : split(next(), ',')) kappas.push_back(std::stod(k));
      } else if (a == "--fit-kappa") {
        fit_kappa = true;
      } else if (a == "--views") {
        scenario.views = std::stoi(next());
        if (scenario.views < 1 || scenario.views > 2) throw std::invalid_argument("--views must be 1 or 2");
      } else if (a == "--pose-noise") {
        const auto v = split(next(), ',');
        if (v.size() != 2) throw std::invalid_argument("--pose-noise wants METRES,DEGREES");
        scenario.pose_noise_m = std::stod(v[0]);
        scenario.pose_noise_deg = std::stod(v[1]);
      } else if (a == "--verify") {
        verify = true;
      } else if (a == "--verify-set") {
        const std::string kv = next();
        const auto eq = kv.find('=');
        if (eq == std::string::npos) throw std::invalid_argument("--verify-set wants key=value, got '" + kv + "'");
        verify_sets.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
      } else if (a == "--quiet") quiet = true;
      else if (a == "--help" || a == "-h") {
        usage();
        return 0;
      } else throw std::invalid_argument("unknown argument '" + a + "'");
    }
    if (seeds.empty()) throw std::invalid_argument("--seeds is required (e.g. 1-100)");
    if (out_dir.empty()) throw std::invalid_argument("--out is required");
    if (variants.empty()) variants.push_back("default");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tomato_eval: %s\n", e.what());
    usage();
    return 2;
  }
  std::filesystem::create_directories(out_dir);
  // The fit's grid: 2 .. 1000 in steps of 2^(1/4) (about 19 %), appended to
  // any --kappa-sweep values.
  const std::size_t fit_from = kappas.size();
  if (fit_kappa)
    for (double k = 2.0; k <= 1000.0 * 1.0001; k *= std::pow(2.0, 0.25)) kappas.push_back(k);

  struct Run {
    std::string name;
    std::unique_ptr<eval::Variant> variant;
    std::vector<eval::TrussScore> scores;
    std::map<char, std::vector<eval::TrussScore>> by_class;
    std::ofstream csv;
  };
  std::vector<Run> runs;
  for (const auto& v : variants) {
    Run r;
    r.name = v;
    try {
      PipelineParams p = eval::variant_params(v);
      for (const auto& [k, val] : sets) eval::set_param(p, k, val);
      r.variant = eval::make_variant(v, p);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "tomato_eval: variant '%s': %s\n", v.c_str(), e.what());
      return 2;
    }
    r.csv.open(out_dir + "/" + v + "_tomatoes.csv");
    r.csv << eval::csv_header();
    runs.push_back(std::move(r));
  }
  std::unique_ptr<eval::VerificationHarness> as_recognised, with_offset;
  std::ofstream vcsv;
  std::map<std::string, std::map<std::string, int>> vcount;  // case -> verdict -> n
  std::map<std::string, int> vision_ok;
  if (verify) {
    eval::VerificationOptions vo;
    try {
      for (const auto& [k, v] : verify_sets) eval::set_verification_option(vo, k, v);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "tomato_eval: --verify-set: %s\n", e.what());
      return 2;
    }
    as_recognised = std::make_unique<eval::VerificationHarness>(vo);
    vo.random_offset_m = 0.05;
    with_offset = std::make_unique<eval::VerificationHarness>(vo);
    std::printf("hand laser: %s\n", as_recognised->describe().c_str());
    vcsv.open(out_dir + "/verification.csv");
    vcsv << "case,class,seed,truth,pick_rank,offset_m,vision_on_pedicel,outcome,verdict,on_pedicel,lateral_error_mm,depth_error_mm,move_mm,confidence,reason\n";
  }
  // kappa sweep: hits of the truth in the HPD50 region per kappa, from the
  // first variant's draws (the draws do not depend on kappa).
  std::vector<int> kappa_hits(kappas.size(), 0);
  int kappa_n = 0;

  for (const auto& cls : classes) {
    const auto c = sim::parse_truss_class(cls);
    if (!c) {
      std::fprintf(stderr, "tomato_eval: unknown class '%s'\n", cls.c_str());
      return 2;
    }
    for (std::uint64_t seed : seeds) {
      const eval::Scenario sc = eval::make_scenario(*c, seed, scenario);
      for (auto& run : runs) {
        const PipelineResult res = run.variant->run(sc);
        const eval::TrussScore ts = eval::score_truss(sc, res);
        run.csv << eval::csv_rows(ts);
        if (&run == &runs.front() && !kappas.empty()) {
          for (const auto& t : ts.tomatoes) {
            if (t.detection < 0) continue;
            const auto& d = res.tomatoes[std::size_t(t.detection)].pedicel.distribution;
            ++kappa_n;
            for (std::size_t k = 0; k < kappas.size(); ++k)
              kappa_hits[k] += PedicelDistribution(d.draws(), kappas[k], 99).in_hpd(sc.truth[std::size_t(t.truth)].pedicel_dir, 0.5);
          }
        }
        if (!quiet) {
          std::printf("%-14s %c %4llu  truth %d detected %d unmatched %d  %6.1f ms  %s\n", run.name.c_str(), *cls.c_str(),
                      static_cast<unsigned long long>(seed), ts.truth, ts.detected, ts.unmatched, ts.times.total_ms(),
                      ts.ok ? "" : (ts.stage + ": " + ts.reason).c_str());
        }
        if (verify && &run == &runs.front()) {
          for (auto* h : {as_recognised.get(), with_offset.get()}) {
            const std::string name = h == as_recognised.get() ? "as_recognised" : "random_offset";
            for (const auto& t : h->run(sc, res)) {
              vcount[name][eval::to_string(t.verdict)]++;
              vcount[name]["trials"]++;
              vision_ok[name] += t.vision_on_pedicel;
              vcsv << name << ',' << t.complexity << ',' << t.seed << ',' << t.truth << ',' << t.pick_rank << ','
                   << t.offset_m << ',' << int(t.vision_on_pedicel) << ',' << to_string(t.outcome) << ','
                   << eval::to_string(t.verdict) << ',' << int(t.on_pedicel) << ',' << 1000 * t.lateral_error_m << ','
                   << 1000 * t.depth_error_m << ',' << 1000 * t.move_m << ',' << t.confidence << ",\"" << t.reason << "\"\n";
            }
          }
        }
        run.by_class[*cls.c_str()].push_back(ts);
        run.scores.push_back(ts);
      }
    }
  }

  for (auto& run : runs) {
    std::ofstream js(out_dir + "/" + run.name + "_summary.json");
    js << "{\n\"variant\": \"" << run.name << "\",\n\"classes\": {\n";
    bool first = true;
    std::printf("\n%s\n%-6s %9s %9s %9s %8s %8s %8s %8s %9s %9s %7s %7s %8s\n", run.name.c_str(), "class", "detected", "rate",
                "visible", "ctr_med", "ctr_p95", "rad_med", "rad_p95", "ped_med", "ped_p95", "hpd50", "cover", "ms_med");
    auto row = [&](const std::string& label, const eval::Summary& s) {
      std::printf("%-6s %4d/%-4d %8.1f%% %8.1f%% %6.2fmm %6.2fmm %6.2fmm %6.2fmm %7.1fdeg %7.1fdeg %6.1f%% %6.1f%% %7.1f\n",
                  label.c_str(), s.detected, s.truth, 100.0 * s.detected / std::max(1, s.truth),
                  100.0 * s.visible_detected / std::max(1, s.visible), s.centre_median_mm, s.centre_p95_mm,
                  s.radius_median_mm, s.radius_p95_mm, s.pedicel_median_deg, s.pedicel_p95_deg, 100 * s.hpd_hit_rate,
                  100 * s.cut_cover_rate, s.total_ms_median);
    };
    for (const auto& [cls, v] : run.by_class) {
      const eval::Summary s = eval::summarize(v);
      row(std::string(1, cls), s);
      js << (first ? "" : ",\n") << "\"" << cls << "\": " << eval::to_json(s);
      first = false;
    }
    const eval::Summary all = eval::summarize(run.scores);
    row("all", all);
    js << ",\n\"all\": " << eval::to_json(all) << "}\n}\n";
  }
  if (verify) {
    std::printf("\nlaser verification (%s): picks of detected tomatoes\n%-15s %7s %9s %9s %9s %9s %12s\n", runs.front().name.c_str(),
                "case", "trials", "aligned", "wrong", "out_view", "nothing", "vision_only");
    for (auto& [name, c] : vcount) {
      const double n = std::max(1, c["trials"]);
      std::printf("%-15s %7d %8.1f%% %8.1f%% %8.1f%% %8.1f%% %11.1f%%\n", name.c_str(), c["trials"], 100 * c["aligned"] / n,
                  100 * c["wrong"] / n, 100 * c["out_of_view"] / n, 100 * c["nothing_found"] / n, 100 * vision_ok[name] / n);
    }
  }
  if (fit_kappa) {
    // Coverage falls with kappa (a narrower kernel, a smaller region), so the
    // grid point closest to 50 % is the fit; ties go to the smaller kappa.
    std::size_t best = fit_from;
    for (std::size_t k = fit_from; k < kappas.size(); ++k)
      if (std::abs(kappa_hits[k] - 0.5 * kappa_n) < std::abs(kappa_hits[best] - 0.5 * kappa_n)) best = k;
    std::ofstream kf(out_dir + "/kappa_fit.csv");
    kf << "kappa,hpd50_hits,n,fitted\n";
    for (std::size_t k = fit_from; k < kappas.size(); ++k)
      kf << kappas[k] << ',' << kappa_hits[k] << ',' << kappa_n << ',' << int(k == best) << '\n';
    if (kappa_n == 0) {
      std::printf("\nkappa fit: no detected tomato to fit on\n");
    } else {
      std::printf("\nkappa fit (%s, %d detected tomatoes): force.kernel_kappa = %.1f puts the truth in the HPD50 region %.1f%% of the time\n",
                  runs.front().name.c_str(), kappa_n, kappas[best], 100.0 * kappa_hits[best] / kappa_n);
    }
    kappas.resize(fit_from);
    kappa_hits.resize(fit_from);
  }
  if (!kappas.empty()) {
    std::ofstream ks(out_dir + "/kappa_sweep.csv");
    ks << "kappa,hpd50_hit_rate,n\n";
    std::printf("\nkappa sweep (%s, %d detected tomatoes): share of true pedicels inside the HPD50 region\n",
                runs.front().name.c_str(), kappa_n);
    for (std::size_t k = 0; k < kappas.size(); ++k) {
      const double rate = kappa_n ? double(kappa_hits[k]) / kappa_n : NAN;
      std::printf("  kappa %7.2f  %5.1f%%\n", kappas[k], 100 * rate);
      ks << kappas[k] << ',' << rate << ',' << kappa_n << '\n';
    }
  }
  return 0;
}
