// `tinyline calib collect` end to end: a calibration session on the simulated
// rail is recorded as a bag by the simulator's virtual sensor node and the bag
// recorder (sim time, no sleeps), collected into the CSV, read back,
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

#include <tiny_laser_driver/calibration_collect.hpp>
#include <tiny_laser_driver/calibration_tool.hpp>

#include "sim_rail_session.hpp"

namespace fs = std::filesystem;
namespace tl = tinyline::tiny_laser_driver;
namespace tt = tinyline::tiny_laser_driver::testing;
using ::testing::HasSubstr;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    char tmpl[] = "/tmp/tinyline_calib_collect_XXXXXX";
    path = ::mkdtemp(tmpl);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
};

std::string rail_scene() { return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/calibration_rail.yaml"; }

int calib(const std::vector<std::string>& args, std::string& out, std::string& err) {
  std::ostringstream o, e;
  const int rc = tl::run_calib_command(args, o, e, {});
  out = o.str();
  err = e.str();
  return rc;
}

double json_field(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\": ");
  if (at == std::string::npos) return std::nan("");
  return std::stod(json.substr(at + key.size() + 4));
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

  const auto r = tl::collect_calibration_data(s.bag_path);
  ASSERT_TRUE(r.ok) << r.reason;
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

  // The CSV round trip and the tool: collect -> fit -> eval on another session.
  std::string out, err;
  ASSERT_EQ(calib({"collect", s.bag_path, "-o", tmp / "rail.csv"}, out, err), 0) << err;
  EXPECT_THAT(out, HasSubstr("36 raw scans on /rail/raw_scan, 36 truths on /rail/scan_truth, 36 paired"));
  EXPECT_THAT(out, HasSubstr(fmt::format("wrote {} rows (2 materials)", d.size())));
  const auto back = tl::read_calibration_csv(tmp / "rail.csv");
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
    const auto r = tl::collect_calibration_data(tmp / "junk.mcap");
    EXPECT_FALSE(r.ok);
    EXPECT_THAT(r.reason, HasSubstr("junk.mcap"));
  }
  EXPECT_THAT(tl::collect_calibration_data(tmp / "missing.mcap").reason, HasSubstr("missing.mcap"));
  // Raw scans but no ground truth (a real sensor's bag).
  {
    namespace bag = tinyline::bag;
    bag::ros2::Ros2Writer w;
    ASSERT_TRUE(w.open(tmp / "raw_only.mcap").ok());
    bag::ChannelId ch = 0;
    ASSERT_TRUE(w.add_topic("/tiny/raw", tinyline::msg::type_support<tinyline::tinyline_msgs::msg::RawScan>(), ch).ok());
    tinyline::tinyline_msgs::msg::RawScan m;
    m.header.frame_id = "laser";
    m.pixels = 272;
    m.pulses = {100};
    m.a.assign(272, 500);
    m.b.assign(272, 500);
    ASSERT_TRUE(w.write(ch, m, 1000, 1000).ok());
    ASSERT_TRUE(w.close().ok());
    const auto r = tl::collect_calibration_data(tmp / "raw_only.mcap");
    EXPECT_FALSE(r.ok);
    EXPECT_THAT(r.reason, HasSubstr("no tinyline_msgs/msg/ScanTruth topic"));
    EXPECT_THAT(r.reason, HasSubstr("raw_only.mcap"));
    tl::CollectParams p;
    p.raw_topic = "/other";
    EXPECT_THAT(tl::collect_calibration_data(tmp / "raw_only.mcap", p).reason,
                HasSubstr("no tinyline_msgs/msg/RawScan topic '/other' (its tinyline_msgs/msg/RawScan topics: /tiny/raw)"));
  }
  // A session whose truths are further from their scans than allowed: nothing pairs.
  {
    auto s = session(tmp / "rail.mcap", 0.3, 0.5, 0.1);
    ASSERT_TRUE(tt::record_sim_rail_session(s).error.empty());
    tl::CollectParams p;
    p.sensor = "someone_else";
    EXPECT_THAT(tl::collect_calibration_data(s.bag_path, p).reason, HasSubstr("no raw scan of sensor 'someone_else'"));
    p.sensor.clear();
    p.pixel_step = 0;
    EXPECT_THAT(tl::collect_calibration_data(s.bag_path, p).reason, HasSubstr("pixel step 0"));
  }
  std::string out, err;
  EXPECT_EQ(calib({"collect", tmp / "raw_only.mcap"}, out, err), 2);
  EXPECT_THAT(err, HasSubstr("collect needs -o DATA.csv"));
  EXPECT_EQ(calib({"collect", tmp / "raw_only.mcap", "-o", tmp / "x.csv"}, out, err), 1);
  EXPECT_THAT(err, HasSubstr("tinyline calib collect: error:"));
  EXPECT_FALSE(fs::exists(tmp / "x.csv"));
}
