// SPDX-License-Identifier: Apache-2.0
#include "sim_rail_session.hpp"

#include <algorithm>
#include <random>

#include <exception>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/registry.hpp>

#include <sim/nodes/register.hpp>
#include <sim/rail.hpp>
#include <sim/system.hpp>

namespace tinyline::tiny_laser_calibration::testing {

SimRailSessionResult record_sim_rail_session(const SimRailSession& s) {
  namespace bus = tinyline::bus;
  namespace bag = tinyline::bag;
  namespace sim = tinyline::sim;
  SimRailSessionResult out;
  try {
    if (s.distances_m.empty() || s.sets_per_distance < 1) throw std::invalid_argument("no rail positions or sets");
    // Hold the scene's shared system with our options: the sensor node gets the same one.
    sim::SystemOptions so;
    so.power_on_age_s = s.power_on_age_s;
    const auto system = sim::SimulatedSystem::shared(s.scene, so);
    const auto target = system->with_scene([&](const sim::Scene& sc) { return sc.world.find(s.target); });
    if (!target) throw std::invalid_argument(s.scene + ": no object named '" + s.target + "'");
    Eigen::Isometry3d pose =
        system->with_scene([&](const sim::Scene& sc) { return sc.world.object(*target).T_world_object; });
    const auto& params = system->sensor(0).params();
    const double period_s = params.acquisition.raw_pulses.back() / params.emitter.pulse_rate_hz;

    bus::ContextOptions co;
    co.clock = bus::ClockType::Sim;
    co.log_sink = std::make_shared<bus::CaptureSink>();
    auto ctx = bus::Context::create(co);
    const double t0 = 100.0;
    ctx->clock().set_sim_time(bus::Time::from_seconds(t0));
    bus::DeterministicExecutor ex(ctx->clock());
    bus::NodeRegistry registry;
    sim::register_nodes(registry);

    bag::RecorderOptions ro;
    ro.path = s.bag_path;
    ro.topics = {s.ns + "/raw_scan", s.ns + "/scan_truth"};
    bus::NodeOptions rec;
    rec.context = ctx;
    rec.name = "recorder";
    auto recorder = std::make_shared<bag::Recorder>(rec, ro);
    ex.add_node(recorder);

    bus::NodeOptions o;
    o.context = ctx;
    o.name = "laser";
    o.ns = s.ns;
    o.param("scene", s.scene).param("power_on_age_s", s.power_on_age_s);
    auto sensor = registry.create("sim", "virtual_sensor", o);
    ex.add_node(sensor);
    ex.spin_until_idle();

    // The sensor ticks every period from t0; move the target half a period
    // before the first set of each position so no set sees two positions.
    double t = t0 + 0.5 * period_s;
    for (double d : s.distances_m) {
      ex.advance_to(bus::Time::from_seconds(t));
      pose.translation().z() = d;
      system->set_object_pose(*target, pose);
      t += s.sets_per_distance * period_s;
    }
    ex.advance_to(bus::Time::from_seconds(t));
    ex.spin_until_idle();
    const auto status = recorder->stop();
    if (!status.ok()) throw std::runtime_error(status.str());
    out.dropped = recorder->stats().dropped;
    ex.remove_node(sensor);

    bag::Reader reader;
    if (auto st = reader.open(s.bag_path); !st.ok()) throw std::runtime_error(st.str());
    for (const auto& [id, ch] : reader.channels()) {
      std::uint64_t n = 0;
      const auto it = reader.summary().statistics.channel_message_counts.find(id);
      if (it != reader.summary().statistics.channel_message_counts.end()) n = it->second;
      if (ch.topic == s.ns + "/raw_scan") out.raw_scans += n;
      if (ch.topic == s.ns + "/scan_truth") out.truths += n;
    }
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  return out;
}

RailConstants measure_rail_constants(const tinyline::sim::SensorParams& params) {
  namespace sim = tinyline::sim;
  sim::RailParams rp;
  rp.target_width_m = 4.0;
  sim::MeasureOptions off;
  off.laser_on = false;
  const int dark = params.lens.dark_pixels, n = params.lens.pixels;
  double spb = 0.0, spp = 0.0;
  {
    const sim::CalibrationRail rail(params, rp);
    const std::vector<int> schedule{100, 400, 700};
    for (int k = 0; k < 5; ++k) {
      const auto set = rail.measure(3600.0, schedule, 900000 + static_cast<std::uint64_t>(k), off);
      for (const auto& r : set.readouts) {
        for (int px = dark; px < n - dark; ++px) {
          spb += r.pulses * r.b[static_cast<std::size_t>(px)];
          spp += static_cast<double>(r.pulses) * r.pulses;
        }
      }
    }
  }
  double sa = 0.0, sb = 0.0;
  {
    sim::SensorParams lit = params;
    lit.environment.ambient_charge_per_pulse = 0.3;
    const sim::CalibrationRail lamp(lit, rp);
    for (int k = 0; k < 5; ++k) {
      const auto set = lamp.measure(3600.0, std::vector<int>{400}, 910000 + static_cast<std::uint64_t>(k), off);
      for (int px = dark; px < n - dark; ++px) {
        sa += set.readouts[0].a[static_cast<std::size_t>(px)];
        sb += set.readouts[0].b[static_cast<std::size_t>(px)];
      }
    }
  }
  return {spp > 0.0 ? spb / spp : 0.0, sa > 0.0 ? sb / sa : 1.0};
}

namespace {

std::vector<std::pair<double, std::string>> shuffled_visits(const RailPlan& plan) {
  std::vector<std::pair<double, std::string>> visits;
  for (int v = 0; v < plan.visits; ++v) {
    for (double d = plan.from_m; d <= plan.to_m + 1e-9; d += plan.step_m) {
      visits.emplace_back(d, plan.materials[static_cast<std::size_t>(v) % plan.materials.size()]);
    }
  }
  std::mt19937 rng(static_cast<unsigned>(plan.seed));
  std::shuffle(visits.begin(), visits.end(), rng);
  return visits;
}

std::vector<int> plan_pixels(const tinyline::sim::SensorParams& params, const RailPlan& plan) {
  std::vector<int> pixels;
  const int dark = params.lens.dark_pixels;
  const int first = plan.pixel_from >= 0 ? plan.pixel_from : dark;
  const int last = plan.pixel_to >= 0 ? plan.pixel_to : params.lens.pixels - dark - 1;
  for (int p = first; p <= last; p += plan.pixel_step) pixels.push_back(p);
  return pixels;
}

}  // namespace

tinyline::tiny_laser_calibration::CalibrationDataset simulate_rail(const tinyline::sim::SensorParams& params,
                                                                   const RailPlan& plan) {
  namespace sim = tinyline::sim;
  namespace cal = tinyline::tiny_laser_calibration;
  sim::RailParams rp;
  rp.material = plan.materials.front();
  rp.target_width_m = 4.0;  // wider than the field of view at 2 m: every pixel sees the target
  sim::CalibrationRail rail(params, rp);
  const auto pixels = plan_pixels(params, plan);
  cal::CalibrationDataset data;
  data.source = "simulated rail";
  data.has_material = true;
  data.extra_names = plan.extra_columns;
  if (plan.session >= 0) data.extra_names.push_back("session");
  double t = plan.power_on_s;
  std::uint64_t index = plan.seed * 100000;
  for (const auto& [distance, material] : shuffled_visits(plan)) {
    rail.set_target_distance(distance);
    rail.set_target_material(material);
    for (int k = 0; k < plan.sets_per_visit; ++k) {
      const sim::SensorSet set = rail.measure(t, params.acquisition.raw_pulses, index++);
      for (const auto& row : sim::calibration_rows(set, rail.world(), pixels, plan.extra_columns)) {
        const auto& truth = set.truth[static_cast<std::size_t>(row.pixel)];
        if (!truth.lit || truth.mixed) continue;
        tinyline::tiny_laser_driver::Readout r;
        r.a = row.a;
        r.b = row.b;
        r.pulses = row.pulses;
        r.temperature_c = row.temperature_c;
        r.pixel = row.pixel;
        r.t_s = set.t_start_s;  // one t_s per set: the tool's frame
        r.extra = row.extra;
        if (plan.session >= 0) r.extra.push_back(plan.session);
        data.add(std::move(r), row.distance_m, row.material);
      }
      t += plan.set_period_s;
    }
  }
  return data;
}

}  // namespace tinyline::tiny_laser_calibration::testing
