// SPDX-License-Identifier: Apache-2.0
// `tinyline calib collect` end to end: a calibration session on the simulated
// rail is recorded as a bag by the simulator's virtual sensor node and the bag
// recorder (sim time, no sleeps), collected into the calibration CSV, read back,
// fitted with `calib fit` and evaluated with `calib eval` on a second session.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>
#include <tinyline/msg/tinyline_msgs/scan_truth.hpp>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_calibration/tool.hpp>
#include <tiny_laser_driver/scan_processor.hpp>
#include <tinyline/bag/reader.hpp>

#include "sim_rail_session.hpp"
#include <tinyline/bus/testing.hpp>

namespace fs = std::filesystem;
namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;
using ::testing::HasSubstr;

namespace {

using TempDir = tinyline::bus::testing::TempDir;

std::string rail_scene() { return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/calibration_rail.yaml"; }

int calib(const std::vector<std::string>& args, std::string& out, std::string& err) {
  std::ostringstream o, e;
  const int rc = cal::run_calib_command(args, o, e, {});
  out = o.str();
  err = e.str();
  return rc;
}

double json_field(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\":");
  if (at == std::string::npos) return std::nan("");
  return std::stod(json.substr(at + key.size() + 3));
}

tt::SimRailSession session(const std::string& bag, double from, double to, double step) {
  tt::SimRailSession s;
  s.scene = rail_scene();
  s.bag_path = bag;
  for (double d = from; d <= to + 1e-9; d += step) s.distances_m.push_back(d);
  s.sets_per_distance = 2;
  return s;
}

}  // namespace

TEST(CalibrationCollect, ARecordedSimulatedRailSessionBecomesTheCalibrationCsv) {
  TempDir tmp;
  const auto s = session(tmp / "rail.mcap", 0.2, 1.9, 0.1);  // 18 positions x 2 sets
  const auto rec = tt::record_sim_rail_session(s);
  ASSERT_TRUE(rec.error.empty()) << rec.error;
  ASSERT_EQ(rec.raw_scans, 36u);
  ASSERT_EQ(rec.truths, 36u);
  EXPECT_EQ(rec.dropped, 0u);

  const auto r = cal::collect_calibration_data(s.bag_path);
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  EXPECT_EQ(r.raw_topic, "/rail/raw_scan");
  EXPECT_EQ(r.truth_topic, "/rail/scan_truth");
  EXPECT_EQ(r.paired, 36u);
  EXPECT_EQ(r.unpaired_scans, 0u);
  EXPECT_EQ(r.dark_pixels, 36u * 16u);
  const auto& d = r.data;
  ASSERT_TRUE(d.has_material);
  // The 1 m wide target and, beyond its edges at the far positions, the wall behind it.
  EXPECT_THAT(d.materials, ::testing::UnorderedElementsAre("white_paper", "wall_paint"));
  // Every row: one of the five read-outs of a lit, unmixed, non-dark pixel.
  EXPECT_EQ(d.size() % 5, 0u);
  EXPECT_EQ(d.size(), 5u * (36u * 256u - r.no_range - r.unlit - r.mixed));
  EXPECT_GT(d.size(), 5u * 36u * 200u);
  // Each set's rows share its t_s; the centre pixel's truth is the rail position
  // (sets in time order, two per position).
  std::map<double, std::vector<std::size_t>> by_set;
  for (std::size_t i = 0; i < d.size(); ++i) by_set[d.readouts[i].t_s].push_back(i);
  ASSERT_EQ(by_set.size(), 36u);
  std::size_t set = 0;
  for (const auto& [t, rows] : by_set) {
    const double rail = s.distances_m[set / 2];
    bool centre = false;
    std::set<int> pulses;
    for (std::size_t i : rows) {
      const auto& ro = d.readouts[i];
      pulses.insert(ro.pulses);
      EXPECT_GE(d.distance_m[i], rail - 1e-4);  // off-axis rays are longer
      if (ro.pixel == 136) {
        centre = true;
        EXPECT_NEAR(d.distance_m[i], rail, 2e-3) << "set " << set;
      }
      EXPECT_EQ(ro.temperature_c, d.readouts[rows.front()].temperature_c);
    }
    EXPECT_TRUE(centre) << "set " << set;
    EXPECT_EQ(pulses, (std::set<int>{20, 100, 200, 400, 700}));
    ++set;
  }
  EXPECT_DOUBLE_EQ(by_set.begin()->first, 0.0);

  // --incidence: the ray's angle to the (square-on) target is the pixel's field angle.
  cal::CollectParams inc;
  inc.incidence_column = true;
  inc.pixel_step = 8;
  const auto ri = cal::collect_calibration_data(s.bag_path, inc);
  ASSERT_TRUE(ri.status.ok()) << ri.status.message;
  ASSERT_EQ(ri.data.extra_names, std::vector<std::string>{"incidence_deg"});
  EXPECT_LT(ri.data.size(), d.size() / 6);
  for (std::size_t i = 0; i < ri.data.size(); ++i) {
    const auto& ro = ri.data.readouts[i];
    ASSERT_EQ(ro.extra.size(), 1u);
    if (ri.data.materials[static_cast<std::size_t>(ri.data.material[i])] != "white_paper") continue;
    if (ro.pixel == 136) {
      EXPECT_LT(ro.extra[0], 0.5);
    } else if (ro.pixel == 8) {
      EXPECT_NEAR(ro.extra[0], 17.7, 1.0);  // atan(2.56 mm / 8 mm)
    }
  }

  // The CSV round trip and the tool: collect -> fit -> eval on another session.
  std::string out, err;
  ASSERT_EQ(calib({"collect", s.bag_path, "-o", tmp / "rail.csv"}, out, err), 0) << err;
  EXPECT_THAT(out, HasSubstr("36 raw scans on /rail/raw_scan, 36 truths on /rail/scan_truth, 36 paired"));
  EXPECT_THAT(out, HasSubstr(fmt::format("wrote {} rows (2 materials)", d.size())));
  const auto back = cal::read_calibration_csv(tmp / "rail.csv");
  ASSERT_EQ(back.size(), d.size());
  for (std::size_t i = 0; i < d.size(); i += 97) {
    EXPECT_EQ(back.readouts[i].a, d.readouts[i].a);
    EXPECT_EQ(back.readouts[i].pixel, d.readouts[i].pixel);
    EXPECT_DOUBLE_EQ(back.readouts[i].t_s, d.readouts[i].t_s);
    EXPECT_NEAR(back.distance_m[i], d.distance_m[i], 1e-9);
  }
  ASSERT_EQ(calib({"fit", tmp / "rail.csv", "-o", tmp / "calib.yaml", "--degree", "5"}, out, err), 0) << err;
  const auto s2 = session(tmp / "heldout.mcap", 0.25, 1.85, 0.2);  // between the training positions
  ASSERT_TRUE(tt::record_sim_rail_session(s2).error.empty());
  ASSERT_EQ(calib({"collect", s2.bag_path, "-o", tmp / "heldout.csv", "--pixel-step", "4"}, out, err), 0) << err;
  ASSERT_EQ(calib({"eval", tmp / "heldout.csv", "--calib", tmp / "calib.yaml"}, out, err), 0) << err;
  // The simulated sensor's per-read-out noise is about 3.6 cm at the driver's choice
  // (tiny_laser_driver/config/calibration/README.md); a wrong pairing or a wrong
  // charge scale would be off by decimetres.
  EXPECT_GT(json_field(out, "n"), 1000.0) << out;
  EXPECT_LT(json_field(out, "rmse_m"), 0.06) << out;
  EXPECT_LT(std::abs(json_field(out, "bias_m")), 0.02) << out;
  std::cout << "held-out session: " << out;
}

TEST(CalibrationCollect, BagsItCannotUseGiveReasons) {
  TempDir tmp;
  // Not a bag.
  {
    std::ofstream(tmp / "junk.mcap") << "this is not an MCAP file";
    const auto r = cal::collect_calibration_data(tmp / "junk.mcap");
    EXPECT_FALSE(r.status.ok());
    EXPECT_THAT(r.status.message, HasSubstr("junk.mcap"));
  }
  const auto missing = cal::collect_calibration_data(tmp / "missing.mcap");
  EXPECT_EQ(missing.status.code, tinyline::StatusCode::OpenFailed) << "the bag's own code";
  EXPECT_THAT(missing.status.message, HasSubstr("missing.mcap"));
  // Raw scans but no ground truth (a real sensor's bag).
  {
    namespace bag = tinyline::bag;
    bag::ros2::Ros2Writer w;
    ASSERT_TRUE(w.open(tmp / "raw_only.mcap").ok());
    bag::ChannelId ch = 0;
    ASSERT_TRUE(
        w.add_topic("/tiny/raw", tinyline::msg::type_support<tinyline::tinyline_msgs::msg::RawScan>(), ch).ok());
    tinyline::tinyline_msgs::msg::RawScan m;
    m.header.frame_id = "laser";
    m.pixels = 272;
    m.pulses = {100};
    m.a.assign(272, 500);
    m.b.assign(272, 500);
    ASSERT_TRUE(w.write(ch, m, 1000, 1000).ok());
    ASSERT_TRUE(w.close().ok());
    const auto r = cal::collect_calibration_data(tmp / "raw_only.mcap");
    EXPECT_EQ(r.status.code, tinyline::StatusCode::NotFound);
    EXPECT_THAT(r.status.message, HasSubstr("no tinyline_msgs/msg/ScanTruth topic"));
    EXPECT_THAT(r.status.message, HasSubstr("raw_only.mcap"));
    cal::CollectParams p;
    p.raw_topic = "/other";
    EXPECT_THAT(cal::collect_calibration_data(tmp / "raw_only.mcap", p).status.message,
                HasSubstr("no tinyline_msgs/msg/RawScan topic '/other'"));
  }
  // A truth that cannot belong to its scan (10 pixels of truth for 272 of charges).
  {
    namespace bag = tinyline::bag;
    bag::ros2::Ros2Writer w;
    ASSERT_TRUE(w.open(tmp / "sizes.mcap").ok());
    bag::ChannelId raw = 0, truth = 0;
    ASSERT_TRUE(w.add_topic("/raw", tinyline::msg::type_support<tinyline::tinyline_msgs::msg::RawScan>(), raw).ok());
    ASSERT_TRUE(
        w.add_topic("/truth", tinyline::msg::type_support<tinyline::tinyline_msgs::msg::ScanTruth>(), truth).ok());
    tinyline::tinyline_msgs::msg::RawScan m;
    m.header.frame_id = "laser";
    m.header.stamp.sec = 5;
    m.pixels = 272;
    m.pulses = {100};
    m.a.assign(272, 500);
    m.b.assign(272, 500);
    tinyline::tinyline_msgs::msg::ScanTruth t;
    t.header = m.header;
    t.sensor = "laser";
    t.range_m.assign(10, 0.5f);
    ASSERT_TRUE(w.write(raw, m, 5'000'000'000, 5'000'000'000).ok());
    ASSERT_TRUE(w.write(truth, t, 5'000'000'000, 5'000'000'000).ok());
    ASSERT_TRUE(w.close().ok());
    const auto r = cal::collect_calibration_data(tmp / "sizes.mcap");
    EXPECT_FALSE(r.status.ok());
    EXPECT_EQ(r.bad_scans, 1u);
    EXPECT_THAT(r.status.message, HasSubstr("no rows"));
    ASSERT_FALSE(r.notes.empty());
    EXPECT_THAT(r.notes.front(), HasSubstr("272 pixels x 1 read-outs, a 272 and b 272 values, truth of 10 pixels"));
  }
  {
    cal::CollectParams p;
    p.raw_topic = "/other";
    EXPECT_THAT(
        cal::collect_calibration_data(tmp / "raw_only.mcap", p).status.message,
        HasSubstr("no tinyline_msgs/msg/RawScan topic '/other' (its tinyline_msgs/msg/RawScan topics: /tiny/raw)"));
  }
  // A good session asked for the wrong sensor or an impossible pixel step.
  {
    auto s = session(tmp / "rail.mcap", 0.3, 0.5, 0.1);
    ASSERT_TRUE(tt::record_sim_rail_session(s).error.empty());
    cal::CollectParams p;
    p.sensor = "someone_else";
    EXPECT_THAT(cal::collect_calibration_data(s.bag_path, p).status.message,
                HasSubstr("no raw scan of sensor 'someone_else'"));
    p.sensor.clear();
    p.pixel_step = 0;
    const auto step = cal::collect_calibration_data(s.bag_path, p);
    EXPECT_EQ(step.status.code, tinyline::StatusCode::InvalidArgument);
    EXPECT_THAT(step.status.message, HasSubstr("pixel step 0"));
  }
  std::string out, err;
  EXPECT_EQ(calib({"collect", tmp / "raw_only.mcap"}, out, err), 2);
  EXPECT_THAT(err, HasSubstr("--output is required"));
  EXPECT_EQ(calib({"collect", tmp / "raw_only.mcap", "-o", tmp / "x.csv"}, out, err), 1);
  EXPECT_THAT(err, HasSubstr("tinyline calib collect: error: not found: "));
  EXPECT_FALSE(fs::exists(tmp / "x.csv"));
}

TEST(CalibrationCollect, TheModelTheToolWritesIsTheModelTheDriverApplies) {
  // collect -> fit --discover -> the YAML into the driver's ScanProcessor, which
  // processes the raw scans of a second session: per pixel the same distance as
  // the model the tool evaluated, and the same error against the truth.
  TempDir tmp;
  const auto train = session(tmp / "rail.mcap", 0.15, 2.0, 0.05);
  const auto test = session(tmp / "heldout.mcap", 0.175, 1.975, 0.1);
  ASSERT_TRUE(tt::record_sim_rail_session(train).error.empty());
  ASSERT_TRUE(tt::record_sim_rail_session(test).error.empty());
  std::string out, err;
  ASSERT_EQ(calib({"collect", train.bag_path, "-o", tmp / "rail.csv", "--pixel-step", "2"}, out, err), 0) << err;
  ASSERT_EQ(calib({"collect", test.bag_path, "-o", tmp / "heldout.csv"}, out, err), 0) << err;
  ASSERT_EQ(calib({"fit", tmp / "rail.csv", "-o", tmp / "calib.yaml", "--discover"}, out, err), 0) << err;
  ASSERT_EQ(calib({"eval", tmp / "heldout.csv", "--calib", tmp / "calib.yaml"}, out, err), 0) << err;
  const double tool_rmse = json_field(out, "rmse_m");
  const double tool_n = json_field(out, "n");

  const auto model = tl::CalibrationModel::load(tmp / "calib.yaml");
  tl::OpticsParams optics;
  optics.focal_mm = 8.0;
  const tl::ScanProcessor processor(model, optics);
  const auto data = cal::read_calibration_csv(tmp / "heldout.csv");
  std::map<std::pair<double, int>, std::vector<std::size_t>> rows;  // (t_s, pixel) -> rows
  for (std::size_t i = 0; i < data.size(); ++i) rows[{data.readouts[i].t_s, data.readouts[i].pixel}].push_back(i);

  namespace bag = tinyline::bag;
  bag::Reader reader;
  ASSERT_TRUE(reader.open(test.bag_path).ok());
  bag::ReadOptions ro;
  ro.topics = {"/rail/raw_scan"};
  double t0 = -1.0, sse = 0.0;
  std::size_t compared = 0;
  const auto status = reader.for_each(ro, [&](const bag::MessageView& v) {
    tinyline::tinyline_msgs::msg::RawScan m;
    EXPECT_TRUE(tinyline::msg::deserialize(v.message.data, m).ok);
    const double stamp = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec;
    if (t0 < 0) t0 = stamp;
    tl::RawSet set;
    for (std::size_t k = 0; k < m.pulses.size(); ++k) {
      tl::RawFrame f;
      f.index = static_cast<std::uint16_t>(k);
      f.last = k + 1 == m.pulses.size();
      f.pulses = m.pulses[k];
      f.temperature_decic = static_cast<std::uint16_t>(std::lround(m.temperature_c * 10.0));
      for (std::size_t i = 0; i < tl::kPixels; ++i) {
        f.a[i] = m.a[k * m.pixels + i];
        f.b[i] = m.b[k * m.pixels + i];
      }
      set.frames.push_back(f);
    }
    const double t_s = stamp - t0;
    const auto scan = processor.process(set, t_s);
    for (std::size_t px = tl::kDarkPixels; px < tl::kPixels - tl::kDarkPixels; ++px) {
      if (scan.status[px] != tl::PixelStatus::kValid) continue;
      const auto it = rows.find({t_s, static_cast<int>(px)});
      if (it == rows.end()) continue;
      for (std::size_t i : it->second) {
        if (data.readouts[i].pulses != scan.pulses[px]) continue;
        tl::Readout r = data.readouts[i];
        r.temperature_c = scan.temperature_c;  // the driver reads the set's temperature in 0.1 degC
        EXPECT_NEAR(scan.distance_m[px], model.distance_m(r), 1e-5) << "pixel " << px << " at " << t_s << " s";
        const double e = scan.distance_m[px] - data.distance_m[i];
        sse += e * e;
        ++compared;
      }
    }
    return true;
  });
  ASSERT_TRUE(status.ok()) << status.str();
  ASSERT_GT(compared, 0.9 * tool_n);
  EXPECT_NEAR(std::sqrt(sse / static_cast<double>(compared)), tool_rmse, 0.05 * tool_rmse);
  std::cout << "driver: " << compared << " pixels, RMSE " << std::sqrt(sse / static_cast<double>(compared))
            << " m; tool eval: " << tool_n << " read-outs, RMSE " << tool_rmse << " m\n";
}
