// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/verification.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <laser_clustering/pedicel_finder.hpp>
#include <laser_clustering/tomato_registration.hpp>
#include <laser_clustering/two_stage.hpp>

#include "harness.hpp"
#include "picking.hpp"
#include "scanner.hpp"
#include <tinyline/common/random.hpp>

namespace tinyline::tomato_reasoning::eval {

namespace lc = tinyline::laser_clustering;

namespace {

using common::splitmix64;
double uniform(std::uint64_t key) { return common::unit_open(splitmix64(key)); }

FinderAnswer::Outcome convert(lc::PedicelOutcome o) {
  switch (o) {
    case lc::PedicelOutcome::kCutHere: return FinderAnswer::Outcome::kCutHere;
    case lc::PedicelOutcome::kMove: return FinderAnswer::Outcome::kMove;
    case lc::PedicelOutcome::kNothingToCut: return FinderAnswer::Outcome::kNothingToCut;
    case lc::PedicelOutcome::kOutOfView: return FinderAnswer::Outcome::kOutOfView;
    case lc::PedicelOutcome::kInvalidInput: return FinderAnswer::Outcome::kInvalidInput;
  }
  return FinderAnswer::Outcome::kInvalidInput;
}

// Where a pedicel segment (a -> b, reference frame) crosses the laser's
// scan plane (y = 0), in laser coordinates; false when it does not.
bool crossing(const Eigen::Isometry3d& T_ref_laser, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
              Eigen::Vector3d& at) {
  const Eigen::Isometry3d T = T_ref_laser.inverse();
  const Eigen::Vector3d pa = T * a, pb = T * b;
  if ((pa.y() > 0) == (pb.y() > 0)) return false;
  const double t = pa.y() / (pa.y() - pb.y());
  at = pa + t * (pb - pa);
  return true;
}

}  // namespace

namespace {

// `text` as a finite number, or std::invalid_argument naming option `key`.
double option_number(const std::string& key, const std::string& text) {
  std::size_t used = 0;
  double v = NAN;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(v))
    throw std::invalid_argument("option '" + key + "': '" + text + "' is not a number");
  return v;
}

// A comma-separated list of heights along the pedicel, each within 5 cm.
std::vector<double> heights_of(const std::string& key, const std::string& value) {
  std::vector<double> heights;
  for (std::size_t from = 0; from < value.size();) {
    const std::size_t comma = std::min(value.find(',', from), value.size());
    const double h = option_number(key, value.substr(from, comma - from));
    if (!(std::abs(h) <= 0.05)) throw std::invalid_argument("option '" + key + "': each must be within 0.05 m");
    heights.push_back(h);
    from = comma + 1;
  }
  return heights;
}

// The pedicel search's options; false when `key` is none of them.
bool set_sweep_option(VerificationOptions& o, const std::string& key, const std::string& value) {
  lc::PedicelSearchParams& p = o.search;
  if (key == "sweep") {
    if (value != "0" && value != "1") throw std::invalid_argument("option 'sweep' must be 0 or 1");
    o.sweep = value == "1";
    return true;
  }
  if (key == "search_turns_deg") {
    o.search_turns_deg.clear();
    for (std::size_t from = 0; from < value.size();) {
      const std::size_t comma = std::min(value.find(',', from), value.size());
      const double deg = option_number(key, value.substr(from, comma - from));
      if (!(std::abs(deg) <= 90)) throw std::invalid_argument("option 'search_turns_deg': each must be within 90");
      o.search_turns_deg.push_back(deg);
      from = comma + 1;
    }
    return true;
  }
  if (key == "sweep_heights_m") {
    p.heights_m = heights_of(key, value);
  } else if (key == "sweep_min_planes") {
    const double v = option_number(key, value);
    if (v != std::floor(v)) throw std::invalid_argument("option 'sweep_min_planes' must be a whole number");
    p.min_planes = static_cast<int>(v);
  } else if (key == "sweep_link_m" || key == "sweep_slope_sd" || key == "sweep_max_slope" ||
             key == "sweep_miss_factor") {
    const double v = option_number(key, value);
    (key == "sweep_link_m"      ? p.link_m
     : key == "sweep_slope_sd"  ? p.slope_sd
     : key == "sweep_max_slope" ? p.max_slope
                                : p.miss_factor) = v;
  } else {
    return false;
  }
  if (auto v = lc::validate(p); !v.valid) throw std::invalid_argument("option '" + key + "': " + v.reason);
  if (std::find(p.heights_m.begin(), p.heights_m.end(), 0.0) == p.heights_m.end())
    throw std::invalid_argument("option 'sweep_heights_m' must hold 0 (the plane of the cut)");
  return true;
}

// The tomato look's options; false when `key` is none of them.
bool set_look_option(VerificationOptions& o, const std::string& key, const std::string& value) {
  if (key == "tomato_look") {
    if (value != "0" && value != "1") throw std::invalid_argument("option 'tomato_look' must be 0 or 1");
    o.tomato_look = value == "1";
  } else if (key == "look_nothing") {
    if (value != "0" && value != "1" && value != "2")
      throw std::invalid_argument("option 'look_nothing' must be 0 (no cut), 1 (blind move) or 2 (unregistered)");
    o.look_nothing = static_cast<LookNothing>(value[0] - '0');
  } else if (key == "look_min_tomatoes") {
    const double v = option_number(key, value);
    if (!(v >= 1 && v <= 10) || v != std::floor(v))
      throw std::invalid_argument("option 'look_min_tomatoes' must be a whole number in [1, 10]");
    o.look_min_tomatoes = static_cast<int>(v);
  } else if (key == "look_heights_m") {
    o.look_heights_m = heights_of(key, value);
  } else if (key == "registered_gate_sd") {
    const double v = option_number(key, value);
    if (!(v > 0)) throw std::invalid_argument("option 'registered_gate_sd' must be > 0");
    o.registered_gate_sd = v;
  } else if (key == "look_back_m" || key == "registered_sd_m" || key == "registered_max_move_m" ||
             key == "look_max_shift_m") {
    const double v = option_number(key, value);
    if (!(v > 0 && v <= 0.2)) throw std::invalid_argument("option '" + key + "' must be in (0, 0.2] m");
    (key == "look_back_m"             ? o.look_back_m
     : key == "registered_sd_m"       ? o.registered_sd_m
     : key == "registered_max_move_m" ? o.registered_max_move_m
                                      : o.look_max_shift_m) = v;
  } else {
    return false;
  }
  return true;
}

}  // namespace

void set_verification_option(VerificationOptions& o, const std::string& key, const std::string& value) {
  auto number = [&](const std::string& text) { return option_number(key, text); };
  if (set_look_option(o, key, value) || set_sweep_option(o, key, value)) return;
  if (key == "pulses") {
    std::vector<int> pulses;
    std::size_t from = 0;
    while (from <= value.size()) {
      const std::size_t comma = std::min(value.find(',', from), value.size());
      const double n = number(value.substr(from, comma - from));
      if (!(n >= 1) || n != std::floor(n))
        throw std::invalid_argument("option 'pulses': counts must be whole and >= 1");
      pulses.push_back(static_cast<int>(n));
      from = comma + 1;
    }
    o.raw_pulses = pulses;
  } else if (key == "cut_offsets_m") {
    std::vector<double> offsets;
    std::size_t from = 0;
    while (from <= value.size()) {
      const std::size_t comma = std::min(value.find(',', from), value.size());
      const double m = number(value.substr(from, comma - from));
      if (!(m > 0 && m < 0.05)) throw std::invalid_argument("option 'cut_offsets_m': each must be in (0, 0.05) m");
      offsets.push_back(m);
      from = comma + 1;
    }
    o.pose.cut_offsets_m = offsets;
  } else if (key == "blade_margin_m" || key == "max_pedicel_width_m") {
    const double v = number(value);
    if (!(v >= 0 && v < 0.05)) throw std::invalid_argument("option '" + key + "' must be in [0, 0.05) m");
    (key == "blade_margin_m" ? o.pose.blades.margin_m : o.max_pedicel_width_m) = v;
  } else if (key == "expectation_sd_m" || key == "max_move_m") {
    const double v = number(value);
    if (!(v > 0)) throw std::invalid_argument("option '" + key + "' must be > 0");
    (key == "max_move_m" ? o.pose.max_move_m : o.expectation_sd_m) = v;
  } else if (key == "pedicel_range_bias_m") {  // "nan": measured on the rod
    const double v = value == "nan" ? NAN : number(value);
    if (!(std::isnan(v) || std::abs(v) < 0.05))
      throw std::invalid_argument("option 'pedicel_range_bias_m' must be nan or within 0.05 m");
    o.pedicel_range_bias_m = v;
  } else if (key == "calibration_max_m") {
    const double v = number(value);
    if (!(v > 0.1 && v <= 2.0)) throw std::invalid_argument("option 'calibration_max_m' must be in (0.1, 2] m");
    o.calibration_max_m = v;
  } else if (key == "rescans") {
    const double v = number(value);
    if (!(v >= 0 && v <= 10) || v != std::floor(v))
      throw std::invalid_argument("option 'rescans' must be a whole number in [0, 10]");
    o.rescans = static_cast<int>(v);
  } else if (key == "approach_far") {
    if (value != "0" && value != "1") throw std::invalid_argument("option 'approach_far' must be 0 or 1");
    o.approach_far = value == "1";
  } else if (key == "max_turn_deg") {  // 0: the straight approach, whatever is in front
    const double v = number(value);
    if (!(v >= 0 && v <= 180)) throw std::invalid_argument("option 'max_turn_deg' must be in [0, 180]");
    o.pose.max_turn_deg = v;
  } else {
    throw std::invalid_argument(
        "unknown option '" + key +
        "' (pulses, expectation_sd_m, max_move_m, max_turn_deg, calibration_max_m, rescans, approach_far, "
        "cut_offsets_m, blade_margin_m, max_pedicel_width_m, tomato_look, look_back_m, registered_sd_m, "
        "registered_gate_sd, registered_max_move_m, look_max_shift_m, "
        "look_min_tomatoes, look_nothing, look_heights_m, sweep, sweep_heights_m, sweep_min_planes, sweep_link_m, "
        "sweep_slope_sd, sweep_max_slope, sweep_miss_factor, search_turns_deg, pedicel_range_bias_m)");
  }
}

const char* to_string(PickVerdict v) {
  switch (v) {
    case PickVerdict::kAligned: return "aligned";
    case PickVerdict::kWrong: return "wrong";
    case PickVerdict::kOutOfView: return "out_of_view";
    case PickVerdict::kNothingFound: return "nothing_found";
  }
  return "?";
}

std::unique_ptr<laser_clustering::eval::Scanner> make_hand_laser(const VerificationOptions& o) {
  laser_clustering::eval::SimScannerOptions so;
  so.sensor_config = o.sensor_config;
  so.raw_pulses = o.raw_pulses;
  so.calibration_max_m = o.calibration_max_m;
  so.calibration_step_m = o.calibration_step_m;
  so.calibration_sets = o.calibration_sets;
  return laser_clustering::eval::make_sim_scanner(so);
}

namespace {

// The hand laser on a pedicel-like rod (the truss's pedicel: 6 mm across,
// its "stem" material, nothing behind it) across the plane at the finder's
// working distances: how much farther than its axis the finder puts it
// (the median over the placements) [m].
double rod_range_bias(lc::eval::Scanner& scanner, const lc::PedicelFinderParams& finder) {
  std::vector<double> errors;
  std::uint64_t seed = 7'000'001;
  for (double z : {0.08, 0.10, 0.12, 0.14, 0.16, 0.18}) {
    for (double x : {-0.02, 0.0, 0.02}) {
      sim::World world;
      const auto stem = world.materials().find("stem");
      if (!stem) throw std::runtime_error("verification: material 'stem' missing from the library");
      world.add({"rod", sim::RodShape{Eigen::Vector3d(x, -0.05, z), Eigen::Vector3d(x, 0.05, z), 0.003},
                 Eigen::Isometry3d::Identity(), *stem});
      const lc::eval::SimulatedScan scan = scanner.scan(world, Eigen::Isometry3d::Identity(), seed++);
      const lc::PedicelDetection d = lc::find_pedicel(scan.scan, lc::cluster_line_scan(scan.scan), finder);
      if (d.outcome == lc::PedicelOutcome::kCutHere || d.outcome == lc::PedicelOutcome::kMove)
        errors.push_back(d.position_xz_m.norm() - std::hypot(x, z));
    }
  }
  if (errors.empty()) throw std::runtime_error("verification: the hand laser found the calibration rod nowhere");
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
  return errors[errors.size() / 2];
}

}  // namespace

VerificationHarness::VerificationHarness(VerificationOptions o) : o_(std::move(o)), scanner_(make_hand_laser(o_)) {
  range_bias_m_ = std::isnan(o_.pedicel_range_bias_m) ? rod_range_bias(*scanner_, finder()) : o_.pedicel_range_bias_m;
}

VerificationHarness::~VerificationHarness() = default;

std::string VerificationHarness::describe() const {
  return scanner_->describe() + "; pedicels read " +
         std::to_string(std::lround(10000 * range_bias_m_) / 10.0).substr(0, 5) + " mm long (" +
         (std::isnan(o_.pedicel_range_bias_m) ? "measured on a rod" : "set") + ")";
}

lc::PedicelFinderParams VerificationHarness::finder() const {
  lc::PedicelFinderParams finder;
  finder.scissors.centre_z_m = o_.pose.throat_z_m;
  finder.scissors.opening_m = o_.scissor_opening_m;
  finder.range_bias_m = range_bias_m_;
  return finder;
}

lc::PedicelDetection VerificationHarness::look(const sim::World& world, const Scenario& s,
                                               const Eigen::Isometry3d& T_ref_laser,
                                               const std::optional<lc::PedicelExpectation>& belief,
                                               std::uint64_t scan_seed) {
  const laser_clustering::eval::SimulatedScan scan =
      scanner_->scan(world, s.truss.T_world_camera * T_ref_laser, scan_seed);
  const lc::TwoStageResult objects = lc::cluster_line_scan(scan.scan);
  return lc::find_pedicel(scan.scan, objects, finder(), belief);
}

namespace {

FinderAnswer answer_of(const lc::PedicelDetection& d) {
  FinderAnswer a;
  a.outcome = convert(d.outcome);
  a.lateral_offset_m = d.lateral_offset_m;
  a.depth_offset_m = d.depth_offset_m;
  a.pedicel_x_m = d.position_xz_m.x();
  a.pedicel_z_m = d.position_xz_m.y();
  a.confidence = d.confidence;
  a.reason = d.reason;
  return a;
}

bool finder_found(const lc::PedicelDetection& d) {
  return d.outcome == lc::PedicelOutcome::kCutHere || d.outcome == lc::PedicelOutcome::kMove;
}

// Scans after the first are keyed apart from every first scan's seed.
constexpr std::uint64_t kRescanSeedStride = 1'000'003;

}  // namespace

std::optional<lc::PedicelExpectation> VerificationHarness::look_at_fruit(const sim::World& world, const Scenario& s,
                                                                         const Eigen::Isometry3d& T_ref_laser,
                                                                         const TrussView& truss,
                                                                         const lc::PedicelExpectation& belief,
                                                                         std::uint64_t scan_seed) {
  if (truss.target < 0 || static_cast<std::size_t>(truss.target) >= truss.fruit.size()) return std::nullopt;
  // The plane through the target fruit's centre (where its section is
  // widest), backed off out of the sensor's short-range bias.
  const Eigen::Isometry3d to_believed = truss.T_ref_laser_believed.inverse();
  const double along = (to_believed * truss.fruit[static_cast<std::size_t>(truss.target)].centre).y();
  const Eigen::Vector3d look_move(0.0, along, -o_.look_back_m);
  std::vector<lc::ExpectedTomato> tomatoes;
  tomatoes.reserve(truss.fruit.size());
  for (const Sphere& f : truss.fruit) tomatoes.push_back({to_believed * f.centre - look_move, f.radius_m});
  const Eigen::Isometry3d T_look = T_ref_laser * Eigen::Translation3d(look_move);
  const lc::eval::SimulatedScan scan = scanner_->scan(world, s.truss.T_world_camera * T_look, scan_seed);
  lc::TomatoRegistrationParams params;
  params.max_shift_m = o_.look_max_shift_m;
  params.min_tomatoes = o_.look_min_tomatoes;
  const lc::TomatoRegistration reg = lc::register_tomatoes(scan.scan, tomatoes, params);
  if (!reg.status.ok()) return std::nullopt;
  lc::PedicelExpectation e = lc::shifted(belief, reg.shift_xz_m);
  e.sd_m = o_.registered_sd_m;
  e.gate_sd = o_.registered_gate_sd;
  return e;
}

namespace {

// The tomato look's scan is keyed apart from the loop's.
constexpr std::uint64_t kLookSeedOffset = 97 * kRescanSeedStride;

// The move to where the registered truss puts the pedicel, seen or not.
lc::PedicelDetection blind_move_to(const lc::PedicelExpectation& e, const lc::PedicelFinderParams& fp) {
  lc::PedicelDetection d;
  d.outcome = lc::PedicelOutcome::kMove;
  d.reason = "nothing pedicel-like where the registered truss puts the pedicel: go there and look again";
  d.position_xz_m = e.position_xz_m;
  d.lateral_offset_m = e.position_xz_m.x() - fp.scissors.centre_x_m;
  d.depth_offset_m = e.position_xz_m.y() - fp.scissors.centre_z_m;
  return d;
}

// The sweep's scans are keyed apart from the loop's and the look's.
constexpr std::uint64_t kSweepSeedOffset = 89 * kRescanSeedStride;
constexpr std::uint64_t kTurnSeedOffset = 83 * kRescanSeedStride;

// The laser turned by `deg` about its y axis through the blade throat (the
// expected pedicel): the throat stays where it was.
Eigen::Isometry3d turned(const Eigen::Isometry3d& T_ref_laser, double deg, double throat_z_m) {
  return T_ref_laser * Eigen::Translation3d(0.0, 0.0, throat_z_m) *
         Eigen::AngleAxisd(deg * M_PI / 180.0, Eigen::Vector3d::UnitY()) * Eigen::Translation3d(0.0, 0.0, -throat_z_m);
}

// `e` as the laser turned by `deg` (turned above) expects it.
lc::PedicelExpectation turned(lc::PedicelExpectation e, double deg, double throat_z_m) {
  const Eigen::Isometry3d T_new_old = turned(Eigen::Isometry3d::Identity(), deg, throat_z_m).inverse();
  const auto in_new = [&](const Eigen::Vector2d& xz) {
    const Eigen::Vector3d p = T_new_old * Eigen::Vector3d(xz.x(), 0.0, xz.y());
    return Eigen::Vector2d(p.x(), p.z());
  };
  e.position_xz_m = in_new(e.position_xz_m);
  for (auto& nb : e.neighbours) nb.position_xz_m = in_new(nb.position_xz_m);
  for (auto& alt : e.alternatives) alt.position_xz_m = in_new(alt.position_xz_m);
  return e;
}

}  // namespace

lc::PedicelSearchResult VerificationHarness::sweep(const sim::World& world, const Scenario& s,
                                                   const Eigen::Isometry3d& T_ref_laser,
                                                   const lc::PedicelExpectation& belief, std::uint64_t scan_seed,
                                                   int& scans) {
  std::vector<lc::SweepScan> planes;
  planes.reserve(o_.search.heights_m.size());
  for (std::size_t i = 0; i < o_.search.heights_m.size(); ++i) {
    const double h = o_.search.heights_m[i];
    const Eigen::Isometry3d T_h = T_ref_laser * Eigen::Translation3d(0.0, h, 0.0);
    const std::uint64_t seed = h == 0.0 ? scan_seed : scan_seed + kSweepSeedOffset + i;
    planes.push_back({h, look(world, s, T_h, belief, seed)});
    ++scans;
  }
  return lc::fuse_sweep(planes, finder(), belief, o_.search);
}

lc::PedicelDetection VerificationHarness::first_look(const sim::World& world, const Scenario& s, PickPose& pose,
                                                     const lc::PedicelExpectation& belief, std::uint64_t scan_seed,
                                                     bool with_truss, bool registered, LoopEnd& end) {
  if (with_truss && o_.sweep) {
    lc::PedicelSearchResult r = sweep(world, s, pose.T_ref_laser, belief, scan_seed, end.scans);
    for (std::size_t i = 0; i < o_.search_turns_deg.size() && !finder_found(r.detection); ++i) {
      // Keep looking: from the side, turned about the expected pedicel.
      const Eigen::Isometry3d T_turn = turned(pose.T_ref_laser, o_.search_turns_deg[i], o_.pose.throat_z_m);
      lc::PedicelSearchResult t = sweep(world, s, T_turn, turned(belief, o_.search_turns_deg[i], o_.pose.throat_z_m),
                                        scan_seed + kTurnSeedOffset * (i + 1), end.scans);
      if (!finder_found(t.detection)) continue;
      pose.T_ref_laser = T_turn;  // the throat stays on the expected pedicel: the cut point with it
      r = std::move(t);
    }
    if (r.cut_height_m != 0.0) {  // the pedicel is seen in another plane: cut there
      const Eigen::Vector3d shift = pose.T_ref_laser.linear() * Eigen::Vector3d(0.0, r.cut_height_m, 0.0);
      pose.T_ref_laser.translation() += shift;
      pose.cut_point += shift;
      end.total_move += shift;
    }
    return r.detection;
  }
  lc::PedicelDetection d = look(world, s, pose.T_ref_laser, belief, scan_seed);
  ++end.scans;
  if (!registered || d.outcome != lc::PedicelOutcome::kNothingToCut) return d;
  // Other heights along the expected pedicel, where nothing hides it.
  for (double h : o_.look_heights_m) {
    const Eigen::Isometry3d T_h = pose.T_ref_laser * Eigen::Translation3d(0.0, h, 0.0);
    const lc::PedicelDetection dh =
        look(world, s, T_h, belief, scan_seed + kLookSeedOffset + static_cast<std::uint64_t>(++end.scans));
    if (finder_found(dh)) return dh;
  }
  return d;
}

LoopEnd VerificationHarness::closed_loop(const sim::World& world, const Scenario& s, PickPose pose,
                                         std::optional<lc::PedicelExpectation> belief, std::uint64_t scan_seed,
                                         bool approach_far, const std::optional<TrussView>& truss) {
  const lc::PedicelFinderParams fp = finder();
  if (!belief) {
    lc::PedicelExpectation expect;
    expect.position_xz_m = Eigen::Vector2d(0.0, o_.pose.throat_z_m);
    expect.sd_m = o_.expectation_sd_m;
    belief = expect;
  }
  LoopEnd end;
  PickPoseParams trust = o_.pose;  // the move limit this loop trusts
  const std::optional<lc::PedicelExpectation> unregistered = belief;
  if (truss && o_.tomato_look) {
    ++end.scans;
    if (auto registered = look_at_fruit(world, s, pose.T_ref_laser, *truss, *belief, scan_seed + kLookSeedOffset)) {
      belief = std::move(registered);
      end.registered = true;
      trust.max_move_m = std::max(trust.max_move_m, o_.registered_max_move_m);
    }
  }
  bool moved = false;  // a move put the hand on a pedicel: end.verification says where
  bool seen = false;   // ... and the laser saw it there (not only the blind move)
  for (int loop_scans = 0;;) {
    lc::PedicelDetection d;
    if (loop_scans == 0) {
      d = first_look(world, s, pose, *belief, scan_seed, truss.has_value(), end.registered, end);
    } else {
      d = look(world, s, pose.T_ref_laser, belief,
               scan_seed + kRescanSeedStride * static_cast<std::uint64_t>(loop_scans));
      ++end.scans;
    }
    const bool last_scan = loop_scans++ >= o_.rescans;
    const bool nothing_registered = end.registered && loop_scans == 1 && d.outcome == lc::PedicelOutcome::kNothingToCut;
    const bool blind =
        nothing_registered && !finder_found(d) && !last_scan && o_.look_nothing == LookNothing::kBlindMove;
    if (blind) d = blind_move_to(*belief, fp);
    if (nothing_registered && !finder_found(d) && o_.look_nothing == LookNothing::kUnregistered) {
      // The same scan, judged as without the look (its move limit too).
      d = look(world, s, pose.T_ref_laser, unregistered, scan_seed);
      trust = o_.pose;
    }
    const Verification v = verify(pose, answer_of(d), trust);
    if (v.will_cut()) {
      end.verification = v;
      end.total_move += v.move;
      end.blind_move = end.blind_move || blind;
      seen = seen || !blind;
      end.belief = blind ? lc::expectation_after_move(fp, belief, d, {d.lateral_offset_m, d.depth_offset_m})
                         : lc::expectation_after_centring(fp, belief, d);
      if (d.outcome != lc::PedicelOutcome::kMove || last_scan) return end;
      // Move, scan again from there, re-centre (4.5).
      moved = true;
      pose.T_ref_laser = v.T_ref_laser_final;
      pose.cut_point = v.cut_point;
      belief = end.belief;
      continue;
    }
    if (moved && seen) return end;  // lost it after a move: the hand stays where that move put it
    const Eigen::Vector2d step(d.lateral_offset_m, d.depth_offset_m);
    if (moved || !(approach_far && finder_found(d) && step.norm() > trust.max_move_m) || last_scan) {
      // (After a blind move that found nothing there either: no cut.)
      end.verification = v;
      end.belief = belief;
      return end;
    }
    // The finder's pedicel is beyond a trusted move: go max_move_m towards it and look again.
    const Eigen::Vector2d part = step * (trust.max_move_m / step.norm());
    const Eigen::Vector3d shift = pose.T_ref_laser.linear() * Eigen::Vector3d(part.x(), 0.0, part.y());
    pose.T_ref_laser.translation() += shift;
    end.total_move += shift;
    pose.cut_point = pose.T_ref_laser * Eigen::Vector3d(0, 0, o_.pose.throat_z_m);
    belief = lc::expectation_after_move(fp, belief, d, part);
  }
}

const char* to_string(BladeCheck::Kind k) {
  switch (k) {
    case BladeCheck::Kind::kClear: return "clear";
    case BladeCheck::Kind::kEmpty: return "empty";
    case BladeCheck::Kind::kJam: return "jam";
  }
  return "?";
}

namespace {

/// Per object of the scan, how many of its points lie in the blades' box (laser frame).
std::vector<int> points_between_blades(const lc::LineScan& scan, const lc::TwoStageResult& objects,
                                       const PickPoseParams& p) {
  std::vector<int> inside(objects.clusters.size(), 0);
  const double half_x = 0.5 * p.blades.opening_m + p.blades.margin_m;
  for (std::size_t i = 0; i < scan.size() && i < objects.labels.size(); ++i) {
    const int label = objects.labels[i];
    if (!scan.valid(i) || label < 0 || static_cast<std::size_t>(label) >= inside.size()) continue;
    const double x = scan.range_m[i] * std::sin(scan.angle_rad[i]), z = scan.range_m[i] * std::cos(scan.angle_rad[i]);
    if (std::abs(x) <= half_x && std::abs(z - p.throat_z_m) <= p.blades.reach_m)
      ++inside[static_cast<std::size_t>(label)];
  }
  return inside;
}

}  // namespace

BladeCheck VerificationHarness::check_blades(const sim::World& world, const Scenario& s,
                                             const Eigen::Isometry3d& T_ref_laser, std::uint64_t scan_seed) {
  const lc::eval::SimulatedScan scan = scanner_->scan(world, s.truss.T_world_camera * T_ref_laser, scan_seed);
  const lc::TwoStageResult objects = lc::cluster_line_scan(scan.scan);
  const std::vector<int> inside = points_between_blades(scan.scan, objects, o_.pose);
  BladeCheck check;
  int found = 0;
  double widest = 0.0;
  for (std::size_t c = 0; c < inside.size(); ++c) {
    if (inside[c] == 0) continue;
    ++found;
    widest = std::max(widest, objects.clusters[c].width_m);
  }
  if (found == 0) return check;
  if (found > 1) {
    check.kind = BladeCheck::Kind::kJam;
    check.what = std::to_string(found) + " objects";
  } else if (widest > o_.max_pedicel_width_m) {
    check.kind = BladeCheck::Kind::kJam;
    check.what = "an object " + std::to_string(std::lround(1000 * widest)) + " mm wide";
  } else {
    check.kind = BladeCheck::Kind::kClear;
  }
  return check;
}

bool throat_on_pedicel(const VerificationOptions& o, const std::pair<Eigen::Vector3d, Eigen::Vector3d>& pedicel,
                       const Eigen::Isometry3d& T_ref_laser, double* lateral, double* depth) {
  Eigen::Vector3d at;
  if (!crossing(T_ref_laser, pedicel.first, pedicel.second, at)) return false;
  if (lateral) *lateral = at.x();
  if (depth) *depth = at.z() - o.pose.throat_z_m;
  return std::abs(at.x()) <= 0.5 * o.scissor_opening_m && std::abs(at.z() - o.pose.throat_z_m) <= o.depth_tolerance_m;
}

std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> true_pedicels(const Scenario& s) {
  const Eigen::Isometry3d T_ref_world = s.truss.T_world_camera.inverse();
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pedicels;
  for (const auto& t : s.truss.tomatoes) pedicels.emplace_back(T_ref_world * t.anchor_m, T_ref_world * t.calyx_m);
  return pedicels;
}

void remove_fruit(const Scenario& s, sim::World& world, int truth) {
  const std::string& name = s.truss.tomatoes[static_cast<std::size_t>(truth)].object_name;
  const std::string prefix = s.truss.params.name + "_";
  const std::string idx = name.substr(name.rfind('_') + 1);
  for (std::size_t o = 0; o < world.size(); ++o) {
    const std::string& n = world.object(static_cast<sim::ObjectId>(o)).name;
    if (n.rfind(name, 0) == 0 || n == prefix + "pedicel_" + idx || n == prefix + "calyx_" + idx) {
      Eigen::Isometry3d far = world.object(static_cast<sim::ObjectId>(o)).T_world_object;
      far.translation() += Eigen::Vector3d(0, 0, -100);
      world.set_pose(static_cast<sim::ObjectId>(o), far);
    }
  }
}

int matched_truth(const Scenario& s, const Tomato& det, double match_m) {
  int truth = -1;
  for (std::size_t t = 0; t < s.truth.size(); ++t)
    if ((det.fit.sphere.centre - s.truth[t].centre_m).norm() <= match_m) truth = static_cast<int>(t);
  return truth;
}

PickPoseParams camera_side(PickPoseParams p) {
  p.approach_from = Eigen::Vector3d::Zero();  // from the camera's side
  return p;
}

TrussView truss_view(const PipelineResult& r, int target, const std::vector<int>& gone,
                     const Eigen::Isometry3d& T_ref_laser_believed) {
  TrussView view;
  view.T_ref_laser_believed = T_ref_laser_believed;
  for (int k = 0; k < static_cast<int>(r.tomatoes.size()); ++k) {
    if (std::find(gone.begin(), gone.end(), k) != gone.end()) continue;
    if (k == target) view.target = static_cast<int>(view.fruit.size());
    view.fruit.push_back(r.tomatoes[static_cast<std::size_t>(k)].fit.sphere);
  }
  return view;
}

std::vector<VerificationTrial> VerificationHarness::run(const Scenario& s, const PipelineResult& r, double match_m) {
  std::vector<VerificationTrial> out;
  // True pedicels (anchor -> calyx) in the reference frame (the first view);
  // the target's index is the truth index.
  const auto pedicels = true_pedicels(s);
  const PickPoseParams pose_params = camera_side(o_.pose);

  // Harvesting goes in pick order: a picked fruit (with its pedicel and
  // sepals) is gone before the next scan.
  sim::World world = s.world;
  std::vector<int> gone;  // detections already picked (or given up on)
  for (int rank = 0; rank < static_cast<int>(r.pick_order.size()); ++rank) {
    const int k = r.pick_order[static_cast<std::size_t>(rank)];
    const int truth = matched_truth(s, r.tomatoes[static_cast<std::size_t>(k)], match_m);
    if (truth < 0) continue;  // spheres that are no tomato are not picked in this evaluation
    VerificationTrial trial;
    trial.complexity = static_cast<char>(s.complexity);
    trial.seed = s.seed;
    trial.truth = truth;
    trial.pick_rank = rank;
    PickPose pose = picking_pose(r, k, pose_params);
    if (!pose.ok()) continue;
    const TrussView truss = truss_view(r, k, gone, pose.T_ref_laser);
    gone.push_back(k);
    if (o_.random_offset_m > 0) {
      // Uniform in the disc square to the pedicel (the laser's x-z plane).
      const std::uint64_t key = splitmix64(s.seed * 7919 + static_cast<std::uint64_t>(k) * 31 + 5);
      const double rad = o_.random_offset_m * std::sqrt(uniform(key)), ang = 2 * M_PI * uniform(key + 1);
      const Eigen::Vector3d off =
          pose.T_ref_laser.linear() * Eigen::Vector3d(rad * std::cos(ang), 0, rad * std::sin(ang));
      pose.T_ref_laser.translation() += off;
      pose.cut_point += off;
      trial.offset_m = rad;
    }
    const auto& target = pedicels[static_cast<std::size_t>(truth)];
    trial.vision_on_pedicel = throat_on_pedicel(o_, target, pose.T_ref_laser, nullptr, nullptr);

    const LoopEnd end = closed_loop(world, s, pose, std::nullopt, s.seed * 1000 + static_cast<std::uint64_t>(k),
                                    o_.approach_far, truss);
    const Verification& v = end.verification;
    trial.scans = end.scans;
    trial.registered = end.registered;
    trial.blind_move = end.blind_move;
    trial.outcome = v.outcome;
    trial.confidence = v.confidence;
    trial.reason = v.reason;
    if (v.will_cut()) {
      double lateral = NAN, depth = NAN;
      trial.on_pedicel = throat_on_pedicel(o_, target, v.T_ref_laser_final, &lateral, &depth);
      trial.lateral_error_m = lateral;
      trial.depth_error_m = depth;
      trial.move_m = end.total_move.norm();
      trial.verdict = trial.on_pedicel ? PickVerdict::kAligned : PickVerdict::kWrong;
    } else {
      trial.verdict =
          v.outcome == Verification::Outcome::kOutOfView ? PickVerdict::kOutOfView : PickVerdict::kNothingFound;
    }
    out.push_back(trial);
    remove_fruit(s, world, truth);  // picked (or given up on): the robot moves on
  }
  return out;
}

}  // namespace tinyline::tomato_reasoning::eval
