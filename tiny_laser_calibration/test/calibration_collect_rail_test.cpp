// SPDX-License-Identifier: Apache-2.0
// `tinyline calib collect --positions`: a real sensor's bag (raw scans only,
// no simulator truth) and the tape-measure log of the rail positions become
// the calibration CSV; the pieces a user gets wrong get errors naming them.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_calibration/tool.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace fs = std::filesystem;
namespace cal = tinyline::tiny_laser_calibration;
namespace bag = tinyline::bag;
using ::testing::HasSubstr;
using tinyline::tinyline_msgs::msg::RawScan;

namespace {

class CollectRail : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tinyline_collect_rail_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }

  // Raw scans as the driver records a real sensor: 272 pixels, two read-outs, at these times.
  std::string write_bag(const std::vector<double>& times) const {
    const std::string p = path("real.mcap");
    bag::ros2::Ros2Writer w;
    EXPECT_TRUE(w.open(p).ok());
    bag::ChannelId id = 0;
    EXPECT_TRUE(w.add_topic("/laser/raw", tinyline::msg::type_support<RawScan>(), id).ok());
    for (std::size_t k = 0; k < times.size(); ++k) {
      RawScan m;
      m.header.frame_id = "laser";
      m.header.stamp.sec = static_cast<std::int32_t>(100 + std::floor(times[k]));
      m.header.stamp.nanosec = static_cast<std::uint32_t>(std::lround((times[k] - std::floor(times[k])) * 1e9));
      m.set_index = static_cast<std::uint32_t>(k);
      m.temperature_c = 40.0f + static_cast<float>(k);
      m.pixels = 272;
      m.pulses = {100, 700};
      for (int r = 0; r < 2; ++r) {
        for (int px = 0; px < 272; ++px) {
          m.a.push_back(static_cast<std::int16_t>(600 * (r + 1) + px % 7));
          m.b.push_back(static_cast<std::int16_t>(300 * (r + 1) + 10 * k));
        }
      }
      const auto t = static_cast<bag::Timestamp>(std::llround((100.0 + times[k]) * 1e9));
      EXPECT_TRUE(w.write(id, m, t, t).ok());
    }
    EXPECT_TRUE(w.close().ok());
    return p;
  }
  std::string write_text(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }

  fs::path dir_;
};

}  // namespace

TEST_F(CollectRail, ATapeMeasureLogReplacesTheTruthTopic) {
  const std::string bag_path = write_bag({0.0, 0.1, 1.0, 1.1, 2.5, 3.0});
  const std::string log = write_text("positions.csv",
                                     "# tape readings, seconds since the first raw scan\n"
                                     "t_from_s,t_to_s,distance_m,material\n"
                                     "0.9,1.5,0.6,white_paper\n"
                                     "0,0.5,0.3,white_paper\n"
                                     "2.9,3.1,1.0,white_paper\n");
  cal::CalibToolEnv env;
  std::ostringstream out, err;
  const std::string csv = path("rail.csv");
  ASSERT_EQ(cal::run_calib_command(
                {"collect", bag_path, "-o", csv, "--positions", log, "--pixels", "130-140", "--focal-mm", "8"}, out,
                err, env),
            0)
      << err.str();
  EXPECT_THAT(out.str(), HasSubstr("6 raw scans on /laser/raw, 5 at a logged rail position, 1 between positions"));
  EXPECT_THAT(err.str(), HasSubstr("1 raw scans fell outside every logged rail position"));
  const auto data = cal::read_calibration_csv(csv);
  ASSERT_EQ(data.size(), 5u * 11u * 2u);  // scans x pixels 130-140 x read-outs
  tinyline::tiny_laser_driver::OpticsParams optics;
  optics.focal_mm = 8.0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const auto& r = data.readouts[i];
    const double logged = r.t_s < 0.6 ? 0.3 : r.t_s < 2.0 ? 0.6 : 1.0;
    EXPECT_NEAR(data.distance_m[i], logged / std::cos(tinyline::tiny_laser_driver::pixel_angle_rad(optics, r.pixel)),
                1e-9);
    EXPECT_GE(r.pixel, 130);
    EXPECT_LE(r.pixel, 140);
  }
  // Charges in charge units (the wire carries ten times), the scan's temperature, t_s since the first scan.
  EXPECT_DOUBLE_EQ(data.readouts[0].a, (600 + 130 % 7) / 10.0);
  EXPECT_DOUBLE_EQ(data.readouts[0].t_s, 0.0);
  EXPECT_EQ(data.materials, std::vector<std::string>{"white_paper"});
  // The CSV is the calibration data set `calib fit` reads: the tool runs on it (too few distances to fit a
  // degree-6 polynomial, said plainly).
  std::ostringstream fout, ferr;
  EXPECT_EQ(
      cal::run_calib_command({"fit", csv, "-o", path("c.yaml"), "--degree", "2", "--no-temperature"}, fout, ferr, env),
      0)
      << ferr.str();
}

TEST_F(CollectRail, LogsItCannotUseGiveReasons) {
  const std::string bag_path = write_bag({0.0, 1.0});
  cal::CalibToolEnv env;
  auto run = [&](const std::string& log_text) {
    std::ostringstream out, err;
    const int rc = cal::run_calib_command(
        {"collect", bag_path, "-o", path("x.csv"), "--positions", write_text("p.csv", log_text)}, out, err, env);
    return std::pair(rc, err.str());
  };
  auto [rc1, e1] = run("t_from_s,t_to_s,distance_m\n0,1,0.3\n0.5,2,0.6\n");
  EXPECT_EQ(rc1, 1);
  EXPECT_THAT(e1, HasSubstr(path("p.csv") + ":3: overlaps the position of line 2"));
  auto [rc2, e2] = run("t_from_s,t_to_s,distance_m\n0,1,far\n");
  EXPECT_THAT(e2, HasSubstr(":2: column 'distance_m': 'far' is not a number"));
  auto [rc3, e3] = run("time,distance\n0,1\n");
  EXPECT_THAT(e3, HasSubstr("expected the header t_from_s,t_to_s,distance_m[,material]"));
  auto [rc4, e4] = run("t_from_s,t_to_s,distance_m\n5,6,0.3\n");
  EXPECT_EQ(rc4, 1);
  EXPECT_THAT(e4, HasSubstr("no raw scan of /laser/raw lies inside a position"));
  EXPECT_FALSE(fs::exists(path("x.csv")));
  std::ostringstream out, err;
  EXPECT_EQ(cal::run_calib_command({"collect", bag_path, "-o", path("x.csv")}, out, err, env), 1);
  EXPECT_THAT(err.str(), HasSubstr("--positions"));  // no truth topic: the error says what to give instead
}
