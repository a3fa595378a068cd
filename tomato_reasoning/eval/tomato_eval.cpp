// SPDX-License-Identifier: Apache-2.0
// tomato_eval: scores the tomato pipeline on seeded simulated trusses
// (docs/tomato_reasoning.md). Each truss is rendered once; every variant runs
// on the same cloud.
//
//   tomato_eval --classes A,B,C --seeds 1-100 --out DIR
//               [--variant NAME]... [--set key=value]... [--kappa-sweep k1,k2,...]
//               [--fit-kappa] [--views 1|2] [--verify] [--closed-loop] [--harvest]
//
// --fit-kappa fits the pedicel distribution's vMF kernel concentration
// (force.kernel_kappa) on the given seeds: the kappa of a log grid whose HPD50
// region holds the true pedicel closest to 50 % of the time (run it on
// fitting seeds, never on the seeds you report).
//
// --harvest runs Table 4.2's harvest trials (eval/harvest.hpp) on the first
// variant's results, written to DIR/harvest.csv and printed per class.
//
// Writes DIR/<variant>_tomatoes.csv (one row per true tomato) and
// DIR/<variant>_summary.json (per class and overall), and prints a table.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "tomato_reasoning/eval/harvest.hpp"
#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/frames_on_disk.hpp"
#include "tomato_reasoning/eval/scoring.hpp"
#include "tomato_reasoning/eval/variants.hpp"
#include "tomato_reasoning/pipeline.hpp"
#include "tomato_reasoning/eval/verification.hpp"

#include "harness.hpp"  // laser_clustering's evaluation: wilson()

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>
#include <tinyline/common/seeds.hpp>

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

/// A non-negative integer; throws naming the text otherwise.
std::uint64_t seed_number(const std::string& s) {
  if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos)
    throw std::invalid_argument("'" + s + "' is not a non-negative integer");
  return std::stoull(s);
}

/// "1-100", "1,5,7-9": the seeds, in order.
std::vector<std::uint64_t> parse_seeds(const std::string& s) {
  std::vector<std::uint64_t> out;
  for (const auto& part : split(s, ',')) {
    const auto dash = part.find('-');
    if (dash == std::string::npos) {
      out.push_back(seed_number(part));
    } else {
      const std::uint64_t a = seed_number(part.substr(0, dash)), b = seed_number(part.substr(dash + 1));
      if (b < a) throw std::invalid_argument("seed range '" + part + "' runs backwards");
      for (std::uint64_t k = a; k <= b; ++k) out.push_back(k);
    }
  }
  if (out.empty()) throw std::invalid_argument("no seeds");
  return out;
}

/// "key=value" as a pair; throws naming the option when there is no '='.
std::pair<std::string, std::string> key_value(const std::string& option, const std::string& kv) {
  const auto eq = kv.find('=');
  if (eq == std::string::npos) throw cli::ParseError(option, "wants key=value, got '" + kv + "'");
  return {kv.substr(0, eq), kv.substr(eq + 1)};
}

std::string lists_for_help() {
  std::string s = "variants:\n";
  for (const auto& v : eval::variant_names()) s += "  " + v + "\n";
  s += "keys for --set:\n";
  for (const auto& k : eval::param_keys()) s += "  " + k + "\n";
  return s;
}

struct Request {
  std::vector<std::string> classes{"A", "B", "C"};
  std::vector<std::uint64_t> seeds;
  std::string out_dir;
  std::vector<std::string> variants;
  std::vector<std::pair<std::string, std::string>> sets, verify_sets, harvest_sets;
  std::vector<double> kappas;
  bool quiet = false, verify = false, fit_kappa = false, closed_loop = false, harvest = false;
  eval::ScenarioOptions scenario;
  std::string via_disk;       ///< frames through RGB-D files in this folder (empty: in memory)
  double depth_noise_mm = 0;  ///< --depth-noise, into scenario.extra_depth_noise_m after parsing
  int order_frames = 0;       ///< pick order over this many re-rendered frames per truss (0: not measured)
  std::string seeds_label;    ///< which seeds and what they are (common/seeds.hpp), on every printed figure
};

/// The conditions of the frames (extra noise, lost pedicels, through files, re-rendered).
void add_frame_options(cli::App& app, Request& r) {
  app.add_option("--views", r.scenario.views, "camera views per truss")->check(cli::range(1, 2))->capture_default_str();
  app.add_option("--depth-noise", r.depth_noise_mm,
                 "extra Gaussian depth noise along each ray [mm] on the rendered frames (a test condition)")
      ->check(cli::non_negative());
  app.add_flag("--drop-pedicel-depth", r.scenario.drop_pedicel_depth,
               "no depth on pixels that see a pedicel or calyx (a camera that loses every thin structure)");
  app.add_option("--order-frames", r.order_frames,
                 "render every truss N more times (own camera noise) and report how often the pick order of the "
                 "first variant stays the same")
      ->check(cli::range(0, 100));
  app.add_option("--via-disk", r.via_disk,
                 "write every frame as an RGB-D folder (PNG, 16-bit depth in mm) under DIR and run the pipeline on "
                 "what the io reader reads back (frames from disk)");
}

/// The laser verification's and the harvest's options (Table 4.3, Table 4.2).
void add_pick_options(cli::App& app, Request& r, std::vector<std::string>& verify_sets,
                      std::vector<std::string>& harvest_sets) {
  app.add_flag("--verify", r.verify,
               "laser verification of every detected tomato's pick (first variant), as recognised and with a random "
               "offset < 5 cm (Table 4.3), written to DIR/verification.csv");
  app.add_option("--verify-set", verify_sets,
                 "the verification's options key=value (pulses=10,20,50,120,300 expectation_sd_m=0.015 "
                 "max_move_m=0.05 max_turn_deg=60; the closed loop: rescans=2 approach_far=0|1), repeatable");
  app.add_flag(
      "--closed-loop", r.closed_loop,
      "the verification's closed loop of thesis 4.5 (move, scan again, re-centre; rescans=2): for --verify and "
      "--harvest; --verify-set overrides");
  app.add_flag("--harvest", r.harvest,
               "harvest trials as Table 4.2 (first variant, as recognised, two attempts, the blades closing in the "
               "truss), written to DIR/harvest.csv");
  app.add_option("--harvest-set", harvest_sets,
                 std::string("the harvest's options key=value, repeatable (") + eval::kHarvestOptionNames +
                     "; eval/harvest.hpp says what each does)");
}

/// Fills `r` from the command line; the exit code when the program stops there.
// The world: elastic rods (the evaluations' default: its truth does not come
// from the force model the reasoning inverts; physics=pendulum for that one),
// then each --truss-set option.
void apply_truss_sets(const std::vector<std::string>& truss_sets, Request& r) {
  r.scenario.truss.physics = tinyline::sim::TrussPhysics::kElasticRod;
  for (const auto& kv : truss_sets) {
    const auto [key, value] = key_value("--truss-set", kv);
    if (const auto why = tinyline::sim::set_truss_option(r.scenario.truss, key, value); !why.ok())
      throw cli::ParseError("--truss-set", why.message);
  }
}

// A tuning run refuses held-out seeds (exit 2); every figure says which
// seeds and which world it comes from.
std::optional<int> check_and_label_seeds(bool tuning, const std::vector<std::string>& truss_sets, Request& r) {
  namespace seeds = tinyline::common::seeds;
  try {
    if (tuning || r.fit_kappa) seeds::require_tuning(seeds::kTomato, r.seeds);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "tomato_eval: %s\n", e.what());
    return 2;
  }
  r.seeds_label = seeds::describe(seeds::kTomato, r.seeds);
  r.seeds_label +=
      r.scenario.truss.physics == tinyline::sim::TrussPhysics::kElasticRod ? ", elastic-rod world" : ", pendulum world";
  for (const auto& kv : truss_sets)
    if (kv.rfind("physics=", 0) != 0) r.seeds_label += ", world " + kv;
  return std::nullopt;
}

std::optional<int> parse(int argc, char** argv, Request& r) {
  cli::App app{
      "Scores the tomato pipeline on seeded simulated trusses (docs/tomato_reasoning.md); every variant "
      "runs on the same clouds. Writes DIR/<variant>_tomatoes.csv and DIR/<variant>_summary.json.",
      "tomato_eval"};
  app.footer(lists_for_help());
  std::string seeds_text;
  std::vector<std::string> sets, verify_sets, harvest_sets;
  std::vector<double> pose_noise;
  app.add_option("--classes", r.classes, "truss complexity classes, comma-separated")
      ->delimiter(',')
      ->check(cli::one_of({"A", "B", "C"}))
      ->capture_default_str();
  app.add_option("--seeds", seeds_text, "seeds: a list of numbers and ranges, e.g. 1-100 or 1,5,7-9")
      ->required()
      ->check(cli::Validator(
          [](std::string& s) -> std::string {
            try {
              (void)parse_seeds(s);
            } catch (const std::exception& e) {
              return "bad seed list '" + s + "': " + e.what();
            }
            return {};
          },
          "SEEDS"));
  app.add_option("--out", r.out_dir, "output directory")->required();
  app.add_option("--variant", r.variants, "pipeline variant (repeatable; default: default)");
  app.add_option("--set", sets, "pipeline parameter key=value (repeatable)");
  app.add_option("--kappa-sweep", r.kappas, "force.kernel_kappa values to score, comma-separated")
      ->delimiter(',')
      ->check(cli::non_negative());
  app.add_flag("--fit-kappa", r.fit_kappa,
               "fit force.kernel_kappa on these seeds (HPD50 coverage closest to 50 %, log grid 2..1000), written to "
               "DIR/kappa_fit.csv");
  app.add_option("--pose-noise", pose_noise, "the second view's pose error: METRES,DEGREES")
      ->delimiter(',')
      ->expected(2)
      ->check(cli::non_negative());
  add_frame_options(app, r);
  add_pick_options(app, r, verify_sets, harvest_sets);
  std::vector<std::string> truss_sets;
  app.add_option(
      "--truss-set", truss_sets,
      "the simulated world's truss option key=value (physics=elastic_rod (the default)|pendulum, stem_bend_deg, "
      "peduncle_curl_deg, pedicel_leaves, rest_tilt_max_deg, ...; sim/scenes/truss.hpp), repeatable");
  app.add_flag("--quiet", r.quiet, "no per-truss lines");
  bool tuning = false;
  app.add_flag("--tuning", tuning,
               "this run is for choosing parameters (as --fit-kappa is): refuse any seed that is not a tuning seed "
               "(docs/evaluation.md)");
  try {
    if (const auto rc = cli::parse_command_line(app, argc, argv)) return rc;
    r.seeds = parse_seeds(seeds_text);
    for (const auto& kv : sets) r.sets.push_back(key_value("--set", kv));
    for (const auto& kv : verify_sets) r.verify_sets.push_back(key_value("--verify-set", kv));
    for (const auto& kv : harvest_sets) r.harvest_sets.push_back(key_value("--harvest-set", kv));
    apply_truss_sets(truss_sets, r);
  } catch (const cli::ParseError& e) {
    (void)app.exit(e);
    return 2;
  }
  if (const auto rc = check_and_label_seeds(tuning, truss_sets, r)) return rc;
  if (pose_noise.size() == 2) {
    r.scenario.pose_noise_m = pose_noise[0];
    r.scenario.pose_noise_deg = pose_noise[1];
  }
  if (r.variants.empty()) r.variants.push_back("default");
  return std::nullopt;
}

/// A bad option found while setting up (exit code 2); the text is printed after "tomato_eval: ".
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One variant's pipeline, its scores and its per-tomato CSV.
struct Run {
  std::string name;
  std::unique_ptr<eval::Variant> variant;
  std::vector<eval::TrussScore> scores;
  std::map<char, std::vector<eval::TrussScore>> by_class;
  std::ostringstream csv;  ///< DIR/<variant>_tomatoes.csv, written when the run ends
};

/// The laser verification of the first variant's picks, as recognised and
/// with a random offset (--verify), and the harvest trials (--harvest, as recognised).
struct PickVerification {
  bool verify = false, harvest = false;
  std::unique_ptr<eval::VerificationHarness> as_recognised, with_offset, harvest_laser;
  std::ostringstream harvest_csv, csv;  ///< DIR/harvest.csv, DIR/verification.csv, written when the run ends
  eval::HarvestOptions harvest_options;
  std::map<char, eval::HarvestCounts> harvested;            // class -> Table 4.2 row
  std::map<std::string, int> causes;                        // why a trial was not picked -> n
  std::map<std::string, std::map<std::string, int>> count;  // case -> verdict -> n
  std::map<std::string, int> vision_ok;
  bool closed_loop = false;  ///< re-scans asked for: the CSV gets a scans column
};

/// Hits of the truth in the HPD50 region per kappa, from the first variant's
/// draws (the draws do not depend on kappa): the --kappa-sweep values, then
/// (--fit-kappa) the fit's grid from `fit_from` on.
struct KappaTally {
  std::vector<double> kappas;
  std::size_t fit_from = 0;
  std::vector<int> hits;
  int n = 0;
};

std::vector<Run> open_runs(const Request& r) {
  std::vector<Run> runs;
  for (const auto& v : r.variants) {
    Run run;
    run.name = v;
    try {
      PipelineParams p = eval::variant_params(v);
      for (const auto& [k, val] : r.sets) eval::set_param(p, k, val);
      run.variant = eval::make_variant(v, p);
    } catch (const std::exception& e) {
      throw UsageError("variant '" + v + "': " + e.what());
    }
    run.csv << eval::csv_header();
    runs.push_back(std::move(run));
  }
  return runs;
}

/// The closed loop of 4.5 as --closed-loop runs it, chosen on tuning seeds
/// (docs/tomato_reasoning.md, "Laser verification").
void set_closed_loop(eval::VerificationOptions& vo) { vo.rescans = 2; }

std::unique_ptr<PickVerification> open_verification(const Request& r) {
  if (!r.verify && !r.harvest) return nullptr;
  eval::VerificationOptions vo;
  if (r.closed_loop) set_closed_loop(vo);
  try {
    for (const auto& [k, v] : r.verify_sets) eval::set_verification_option(vo, k, v);
  } catch (const std::exception& e) {
    throw UsageError(std::string("--verify-set: ") + e.what());
  }
  auto out = std::make_unique<PickVerification>();
  try {
    for (const auto& [k, v] : r.harvest_sets) eval::set_harvest_option(out->harvest_options, k, v);
  } catch (const std::exception& e) {
    throw UsageError(std::string("--harvest-set: ") + e.what());
  }
  out->verify = r.verify;
  out->harvest = r.harvest;
  if (r.harvest) {  // the harvest's own laser; the verification's below
    out->harvest_laser = std::make_unique<eval::VerificationHarness>(eval::harvest_laser(vo, out->harvest_options));
    std::printf("harvest's hand laser: %s\n", out->harvest_laser->describe().c_str());
    out->harvest_csv
        << "class,seed,truth,detected,pick_rank,attempts,scans,outcome,cuts,jammed_on,why,probed,on_pedicel\n";
  }
  if (!r.verify) return out;
  out->as_recognised = std::make_unique<eval::VerificationHarness>(vo);
  std::printf("hand laser: %s\n", out->as_recognised->describe().c_str());
  vo.random_offset_m = 0.05;
  out->with_offset = std::make_unique<eval::VerificationHarness>(vo);
  out->closed_loop = vo.rescans > 0;
  out->csv << "case,class,seed,truth,pick_rank,offset_m,vision_on_pedicel,outcome,verdict,on_pedicel,lateral_error_mm,"
              "depth_error_mm,move_mm,confidence,reason"
           << (out->closed_loop ? ",scans,registered,blind_move\n" : ",registered\n");
  return out;
}

KappaTally kappa_tally(const Request& r) {
  KappaTally t;
  t.kappas = r.kappas;
  t.fit_from = t.kappas.size();
  // The fit's grid: 2 .. 1000 in steps of 2^(1/4) (about 19 %).
  if (r.fit_kappa)
    for (double k = 2.0; k <= 1000.0 * 1.0001; k *= std::pow(2.0, 0.25)) t.kappas.push_back(k);
  t.hits.assign(t.kappas.size(), 0);
  return t;
}

void count_kappa_hits(KappaTally& tally, const eval::Scenario& sc, const PipelineResult& res,
                      const eval::TrussScore& ts) {
  for (const auto& t : ts.tomatoes) {
    if (t.detection < 0) continue;
    const auto& d = res.tomatoes[std::size_t(t.detection)].pedicel.distribution;
    ++tally.n;
    for (std::size_t k = 0; k < tally.kappas.size(); ++k)
      tally.hits[k] +=
          PedicelDistribution(d.draws(), tally.kappas[k], 99).in_hpd(sc.truth[std::size_t(t.truth)].pedicel_dir, 0.5);
  }
}

/// A trial's failure cause in a few words: what jammed the blades (its
/// kind: fruit, peduncle, main stem, pedicels), or why the last attempt did
/// not close (the reason with its figures as N); "" when picked.
std::string cause_of(const eval::HarvestTrial& t) {
  using O = eval::HarvestOutcome;
  if (t.outcome == O::kPickedFirst || t.outcome == O::kPickedSecond) return "";
  if (t.outcome == O::kKnockedOff) return "knocked off by another fruit's cut";
  if (t.outcome == O::kCutFailure) return "jammed on " + t.jammed_on.substr(0, t.jammed_on.find_first_of("0123456789"));
  if (!t.detected) return "not detected";
  const std::string last = t.why.substr(t.why.rfind(';') + 1);
  if (last.empty()) return "left after: " + t.cuts.substr(t.cuts.rfind(';') + 1);
  return "left: " + eval::without_figures(last);
}

void harvest_truss(PickVerification& v, const eval::Scenario& sc, const PipelineResult& res) {
  for (const auto& t : eval::harvest(*v.harvest_laser, sc, res, v.harvest_options)) {
    v.harvested[t.complexity].add(t);
    if (const std::string c = cause_of(t); !c.empty()) v.causes[c]++;
    v.harvest_csv << t.complexity << ',' << t.seed << ',' << t.truth << ',' << int(t.detected) << ',' << t.pick_rank
                  << ',' << t.attempts << ',' << t.scans << ',' << eval::to_string(t.outcome) << ',' << t.cuts << ",\""
                  << t.jammed_on << "\",\"" << t.why << "\",\"" << t.probed << "\",\"" << t.on_pedicel << "\"\n";
  }
}

void verify_picks(PickVerification& v, const eval::Scenario& sc, const PipelineResult& res) {
  if (v.harvest) harvest_truss(v, sc, res);
  if (!v.verify) return;
  for (auto* h : {v.as_recognised.get(), v.with_offset.get()}) {
    const std::string name = h == v.as_recognised.get() ? "as_recognised" : "random_offset";
    for (const auto& t : h->run(sc, res)) {
      v.count[name][eval::to_string(t.verdict)]++;
      v.count[name]["trials"]++;
      v.vision_ok[name] += t.vision_on_pedicel;
      v.csv << name << ',' << t.complexity << ',' << t.seed << ',' << t.truth << ',' << t.pick_rank << ',' << t.offset_m
            << ',' << int(t.vision_on_pedicel) << ',' << to_string(t.outcome) << ',' << eval::to_string(t.verdict)
            << ',' << int(t.on_pedicel) << ',' << 1000 * t.lateral_error_m << ',' << 1000 * t.depth_error_m << ','
            << 1000 * t.move_m << ',' << t.confidence << ",\"" << t.reason << '"';
      if (v.closed_loop) v.csv << ',' << t.scans;
      v.csv << ',' << int(t.registered);
      if (v.closed_loop) v.csv << ',' << int(t.blind_move);
      v.csv << '\n';
    }
  }
}

void print_truss_line(const Run& run, char cls, std::uint64_t seed, const eval::TrussScore& ts) {
  std::printf("%-14s %c %4llu  truth %d detected %d unmatched %d  %6.1f ms  %s\n", run.name.c_str(), cls,
              static_cast<unsigned long long>(seed), ts.truth, ts.detected, ts.unmatched, ts.times.total_ms(),
              ts.ok ? "" : (ts.stage + ": " + ts.reason).c_str());
}

/// Per class: trusses whose pick order was the same in every re-rendered
/// frame, and frames whose first pick was the first frame's.
struct OrderTally {
  int trusses = 0, stable = 0, frames = 0, same_first = 0;
};

// The scenario's views rendered `n` more times, the variant run on each.
void tally_order(const Request& r, const eval::Variant& variant, const eval::Scenario& sc, OrderTally& t) {
  eval::Scenario again = sc;
  std::vector<std::vector<int>> orders;
  for (int f = 1; f <= r.order_frames; ++f) {
    for (std::size_t v = 0; v < again.clouds.size(); ++v)
      again.clouds[v] = eval::render_again(sc, r.scenario, v, sc.seed * 16 + 1000 * std::uint64_t(f) + v);
    orders.push_back(eval::pick_order_in_truth(sc, variant.run(again)));
  }
  ++t.trusses;
  bool stable = true;
  for (const auto& o : orders) {
    stable = stable && o == orders.front();
    ++t.frames;
    t.same_first += !o.empty() && !orders.front().empty() && o.front() == orders.front().front();
  }
  t.stable += stable;
}

void print_order(const std::map<char, OrderTally>& by_class, int frames) {
  std::printf("\npick order over %d re-rendered frames per truss\n%-6s %16s %20s\n", frames, "class", "same order",
              "same first pick");
  OrderTally all;
  auto row = [](const std::string& label, const OrderTally& t) {
    std::printf("%-6s %4d/%-4d %5.1f%% %6d/%-6d %5.1f%%\n", label.c_str(), t.stable, t.trusses,
                100.0 * t.stable / std::max(1, t.trusses), t.same_first, t.frames,
                100.0 * t.same_first / std::max(1, t.frames));
  };
  for (const auto& [cls, t] : by_class) {
    row(std::string(1, cls), t);
    all.trusses += t.trusses, all.stable += t.stable, all.frames += t.frames, all.same_first += t.same_first;
  }
  row("all", all);
}

/// Every variant on every truss (each rendered once), scored; the first
/// variant's results also feed the kappa tally and the verification.
void evaluate(const Request& r, std::vector<Run>& runs, PickVerification* verification, KappaTally& tally,
              std::map<char, OrderTally>& order) {
  for (const auto& cls : r.classes) {
    const auto c = sim::parse_truss_class(cls);
    if (!c) throw UsageError("unknown class '" + cls + "'");
    for (std::uint64_t seed : r.seeds) {
      eval::Scenario sc = eval::make_scenario(*c, seed, r.scenario);
      if (!r.via_disk.empty()) eval::round_trip_through_files(sc, r.via_disk);
      if (r.order_frames > 0) tally_order(r, *runs.front().variant, sc, order[*cls.c_str()]);
      for (auto& run : runs) {
        const bool first = &run == &runs.front();
        const PipelineResult res = run.variant->run(sc);
        const eval::TrussScore ts = eval::score_truss(sc, res);
        run.csv << eval::csv_rows(ts);
        if (first && !tally.kappas.empty()) count_kappa_hits(tally, sc, res, ts);
        if (!r.quiet) print_truss_line(run, *cls.c_str(), seed, ts);
        if (verification && first) verify_picks(*verification, sc, res);
        run.by_class[*cls.c_str()].push_back(ts);
        run.scores.push_back(ts);
      }
    }
  }
}

void print_summary_row(const std::string& label, const eval::Summary& s) {
  std::printf("%-6s %4d/%-4d %8.1f%% %8.1f%% %6.2fmm %6.2fmm %6.2fmm %6.2fmm %7.1fdeg %7.1fdeg %6.1f%% %6.1f%% %7.1f\n",
              label.c_str(), s.detected, s.truth, 100.0 * s.detected / std::max(1, s.truth),
              100.0 * s.visible_detected / std::max(1, s.visible), s.centre_median_mm, s.centre_p95_mm,
              s.radius_median_mm, s.radius_p95_mm, s.pedicel_median_deg, s.pedicel_p95_deg, 100 * s.hpd_hit_rate,
              100 * s.cut_cover_rate, s.total_ms_median);
}

/// The seen pedicel and the sphere bias per class: how often the pedicel was
/// seen, the direction error before (force model) and after (posterior), and
/// the signed radius and along-the-ray centre errors.
void print_evidence(const Run& run) {
  std::printf("\n%s: pedicel evidence and sphere bias\n%-6s %14s %10s %10s %12s %12s %10s %10s\n", run.name.c_str(),
              "class", "seen", "prior_med", "post_med", "seen_prior", "seen_post", "rad_bias", "toward_cam");
  auto row = [](const std::string& label, const eval::Summary& s) {
    std::printf("%-6s %5d/%-4d %5.1f%% %8.2fdeg %8.2fdeg %10.2fdeg %10.2fdeg %8.2fmm %8.2fmm\n", label.c_str(), s.seen,
                s.detected, 100.0 * s.seen / std::max(1, s.detected), s.prior_pedicel_median_deg, s.pedicel_median_deg,
                s.seen_prior_median_deg, s.seen_posterior_median_deg, s.radius_bias_mm, s.centre_toward_camera_mm);
  };
  for (const auto& [cls, v] : run.by_class) row(std::string(1, cls), eval::summarize(v));
  row("all", eval::summarize(run.scores));
}

/// Per class and overall: printed, and DIR/<variant>_summary.json.
void write_summary(const Run& run, const Request& r) {
  files::AtomicStream js(r.out_dir + "/" + run.name + "_summary.json");
  js << "{\n\"variant\": \"" << run.name << "\",\n\"seeds\": \"" << r.seeds_label << "\",\n\"classes\": {\n";
  std::printf("\n%s (%s)\n%-6s %9s %9s %9s %8s %8s %8s %8s %9s %9s %7s %7s %8s\n", run.name.c_str(),
              r.seeds_label.c_str(), "class", "detected", "rate", "visible", "ctr_med", "ctr_p95", "rad_med", "rad_p95",
              "ped_med", "ped_p95", "hpd50", "cover", "ms_med");
  bool first = true;
  for (const auto& [cls, v] : run.by_class) {
    const eval::Summary s = eval::summarize(v);
    print_summary_row(std::string(1, cls), s);
    js << (first ? "" : ",\n") << "\"" << cls << "\": " << eval::to_json(s);
    first = false;
  }
  const eval::Summary all = eval::summarize(run.scores);
  print_summary_row("all", all);
  print_evidence(run);
  js << ",\n\"all\": " << eval::to_json(all) << "}\n}\n";
  js.commit();
}

/// "k/n = p% [lo, hi]" (Wilson 95 %).
std::string rate(int k, int n) {
  const auto w = laser_clustering::eval::wilson(k, n);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%d/%d = %.1f%% [%.1f, %.1f]", k, n, 100 * w.p, 100 * w.lo, 100 * w.hi);
  return buf;
}

/// Table 4.2 per class, each count of its trials with its Wilson interval.
void print_harvest(const PickVerification& v, const std::string& variant, const std::string& seeds_label) {
  std::printf("\nharvest trials (%s; %s), Table 4.2: share of trials\n", variant.c_str(), seeds_label.c_str());
  std::printf(
      "| class | trials | SD | SP(1) | SP(2) | HS (left for a human) | CF | knocked off "
      "|\n|---|---|---|---|---|---|---|---|\n");
  eval::HarvestCounts all;
  auto row = [](const std::string& name, const eval::HarvestCounts& c) {
    std::printf("| %s | %d | %s | %s | %s | %s | %s | %s |\n", name.c_str(), c.trials,
                rate(c.detected, c.trials).c_str(), rate(c.picked_first, c.trials).c_str(),
                rate(c.picked_second, c.trials).c_str(), rate(c.left_for_human, c.trials).c_str(),
                rate(c.cut_failures, c.trials).c_str(), rate(c.knocked_off, c.trials).c_str());
  };
  for (const auto& [cls, c] : v.harvested) {
    row(std::string(1, cls), c);
    all += c;
  }
  row("all", all);
  std::printf("\nwhy trials were not picked (%s)\n| cause | trials |\n|---|---|\n", seeds_label.c_str());
  for (const auto& [cause, n] : v.causes) std::printf("| %s | %s |\n", cause.c_str(), rate(n, all.trials).c_str());
}

void print_verification(PickVerification& v, const std::string& variant, const std::string& seeds_label) {
  std::printf("\nlaser verification (%s; %s): picks of detected tomatoes\n%-15s %7s %9s %9s %9s %9s %12s\n",
              variant.c_str(), seeds_label.c_str(), "case", "trials", "aligned", "wrong", "out_view", "nothing",
              "vision_only");
  for (auto& [name, c] : v.count) {
    const double n = std::max(1, c["trials"]);
    std::printf("%-15s %7d %8.1f%% %8.1f%% %8.1f%% %8.1f%% %11.1f%%\n", name.c_str(), c["trials"],
                100 * c["aligned"] / n, 100 * c["wrong"] / n, 100 * c["out_of_view"] / n, 100 * c["nothing_found"] / n,
                100 * v.vision_ok[name] / n);
  }
}

/// The fit's grid point whose HPD50 coverage is closest to 50 %, written to
/// DIR/kappa_fit.csv and printed; the grid then leaves the tally.
void report_kappa_fit(KappaTally& t, const std::string& variant, const Request& r) {
  // Coverage falls with kappa (a narrower kernel, a smaller region), so the
  // grid point closest to 50 % is the fit; ties go to the smaller kappa.
  std::size_t best = t.fit_from;
  for (std::size_t k = t.fit_from; k < t.kappas.size(); ++k)
    if (std::abs(t.hits[k] - 0.5 * t.n) < std::abs(t.hits[best] - 0.5 * t.n)) best = k;
  files::AtomicStream kf(r.out_dir + "/kappa_fit.csv");
  kf << "kappa,hpd50_hits,n,fitted\n";
  for (std::size_t k = t.fit_from; k < t.kappas.size(); ++k)
    kf << t.kappas[k] << ',' << t.hits[k] << ',' << t.n << ',' << int(k == best) << '\n';
  kf.commit();
  if (t.n == 0) {
    std::printf("\nkappa fit: no detected tomato to fit on\n");
  } else {
    std::printf(
        "\nkappa fit (%s, %s, %d detected tomatoes): force.kernel_kappa = %.1f puts the truth in the HPD50 region "
        "%.1f%% of the time\n",
        variant.c_str(), r.seeds_label.c_str(), t.n, t.kappas[best], 100.0 * t.hits[best] / t.n);
  }
  t.kappas.resize(t.fit_from);
  t.hits.resize(t.fit_from);
}

/// The --kappa-sweep values' HPD50 hit rates: printed and DIR/kappa_sweep.csv.
void report_kappa_sweep(const KappaTally& t, const std::string& variant, const Request& r) {
  files::AtomicStream ks(r.out_dir + "/kappa_sweep.csv");
  ks << "kappa,hpd50_hit_rate,n\n";
  std::printf("\nkappa sweep (%s, %s, %d detected tomatoes): share of true pedicels inside the HPD50 region\n",
              variant.c_str(), r.seeds_label.c_str(), t.n);
  for (std::size_t k = 0; k < t.kappas.size(); ++k) {
    const double rate = t.n ? double(t.hits[k]) / t.n : NAN;
    std::printf("  kappa %7.2f  %5.1f%%\n", t.kappas[k], 100 * rate);
    ks << t.kappas[k] << ',' << rate << ',' << t.n << '\n';
  }
  ks.commit();
}

/// The per-tomato, verification and harvest CSVs, each renamed into place.
void write_tables(const std::vector<Run>& runs, const PickVerification* v, const Request& r) {
  for (const auto& run : runs) files::write_atomically(r.out_dir + "/" + run.name + "_tomatoes.csv", run.csv.view());
  if (v && v->verify) files::write_atomically(r.out_dir + "/verification.csv", v->csv.view());
  if (v && v->harvest) files::write_atomically(r.out_dir + "/harvest.csv", v->harvest_csv.view());
}

/// Every file the run may write, checked before any truss is simulated.
/// The frames --via-disk writes (eval::round_trip_through_files: a folder
/// per class, seed and view), checked before any work.
bool via_disk_allowed(const Request& r) {
  namespace fs = std::filesystem;
  if (r.via_disk.empty()) return true;
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(r.via_disk, ec);
  if (fs::exists(st) && !fs::is_directory(st)) {
    std::fprintf(stderr, "tomato_eval: --via-disk %s is not a folder: left as it is\n", r.via_disk.c_str());
    return false;
  }
  for (const auto& c : r.classes)
    for (const std::uint64_t seed : r.seeds)
      for (int v = 0; v < r.scenario.views; ++v)
        for (const char* name : {"rgb/000000.png", "depth/000000.png", "intrinsics.yaml"}) {
          const fs::path file = fs::path(r.via_disk) / (c + std::to_string(seed) + "_v" + std::to_string(v)) / name;
          if (!files::output_allowed("tomato_eval", file.string())) return false;
        }
  return true;
}

bool outputs_allowed(const Request& r) {
  std::vector<std::string> names{"verification.csv", "harvest.csv", "kappa_fit.csv", "kappa_sweep.csv"};
  for (const auto& v : r.variants) {
    names.push_back(v + "_tomatoes.csv");
    names.push_back(v + "_summary.json");
  }
  for (const auto& n : names)
    if (!files::output_allowed("tomato_eval", r.out_dir + "/" + n)) return false;
  return via_disk_allowed(r);
}

}  // namespace

int main(int argc, char** argv) {
  Request request;
  if (const auto rc = parse(argc, argv, request)) return *rc;
  request.scenario.extra_depth_noise_m = request.depth_noise_mm / 1000.0;
  if (!outputs_allowed(request)) return 1;
  if (std::error_code ec; !std::filesystem::create_directories(request.out_dir, ec) && ec) {
    std::fprintf(stderr, "tomato_eval: cannot create the output directory %s: %s\n", request.out_dir.c_str(),
                 ec.message().c_str());
    return 1;
  }
  std::printf("%s\n", request.seeds_label.c_str());
  try {
    KappaTally tally = kappa_tally(request);
    std::vector<Run> runs = open_runs(request);
    const std::unique_ptr<PickVerification> verification = open_verification(request);
    std::map<char, OrderTally> order;
    evaluate(request, runs, verification.get(), tally, order);
    if (request.order_frames > 0) print_order(order, request.order_frames);
    write_tables(runs, verification.get(), request);
    for (const auto& run : runs) write_summary(run, request);
    const std::string& first = runs.front().name;
    if (verification && verification->verify) print_verification(*verification, first, request.seeds_label);
    if (verification && verification->harvest) print_harvest(*verification, first, request.seeds_label);
    if (request.fit_kappa) report_kappa_fit(tally, first, request);
    if (!tally.kappas.empty()) report_kappa_sweep(tally, first, request);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "tomato_eval: %s\n", e.what());
    return 2;
  } catch (const files::FileError& e) {
    std::fprintf(stderr, "tomato_eval: %s\n", e.what());
    return 1;
  }
  return 0;
}
