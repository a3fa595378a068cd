// SPDX-License-Identifier: Apache-2.0
// What `tinyline calib collect -o` and `calib fit -o` write, and what they
// never replace: their own input, a symbolic link, a FIFO; a command that
// fails (here on a file size limit, as on a full disk) leaves the existing
// output as it was.
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tiny_laser_calibration/tool.hpp>
#include <tinyline/bus/testing.hpp>

#include "sim_rail_session.hpp"

namespace fs = std::filesystem;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;
using ::testing::HasSubstr;
using TempDir = tinyline::bus::testing::TempDir;

namespace {

int calib(const std::vector<std::string>& args, std::string& err) {
  std::ostringstream o, e;
  const int rc = cal::run_calib_command(args, o, e, {});
  err = e.str();
  return rc;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A short rail session recorded as a bag (sim time, no sleeps).
std::string record_bag(const TempDir& tmp) {
  tt::SimRailSession s;
  s.scene = std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/calibration_rail.yaml";
  s.bag_path = tmp / "rail.mcap";
  for (double d = 0.2; d <= 1.9 + 1e-9; d += 0.1) s.distances_m.push_back(d);
  s.sets_per_distance = 2;
  const auto rec = tt::record_sim_rail_session(s);
  EXPECT_TRUE(rec.error.empty()) << rec.error;
  return s.bag_path;
}

// Runs `body` with writes past `bytes` failing (EFBIG), as a full disk would fail them.
template <typename F>
void with_file_size_limit(rlim_t bytes, F body) {
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  const auto old_handler = ::signal(SIGXFSZ, SIG_IGN);
  rlimit low = old;
  low.rlim_cur = bytes;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &low), 0);
  body();
  ::setrlimit(RLIMIT_FSIZE, &old);
  ::signal(SIGXFSZ, old_handler);
}

}  // namespace

TEST(CalibOutput, CollectAndFitNeverReplaceTheirInputALinkOrAFifoAndAFailureKeepsTheOldOutput) {
  TempDir tmp;
  const std::string bag = record_bag(tmp);
  const std::string bag_bytes = slurp(bag);
  std::string err;

  // Its own input, under its own name and through a hard link.
  EXPECT_EQ(calib({"collect", bag, "-o", bag}, err), 1);
  EXPECT_THAT(err, HasSubstr("is also an input of this command"));
  fs::create_hard_link(bag, tmp / "alias.csv");
  EXPECT_EQ(calib({"collect", bag, "-o", tmp / "alias.csv"}, err), 1);
  EXPECT_EQ(slurp(bag), bag_bytes);
  // The tape-measure log is an input too.
  const std::string log = tmp / "log.csv";
  std::ofstream(log) << "t_from_s,t_to_s,distance_m\n0,100,0.5\n";
  EXPECT_EQ(calib({"collect", bag, "--positions", log, "-o", log}, err), 1);
  EXPECT_THAT(err, HasSubstr("is also an input of this command"));
  EXPECT_EQ(slurp(log), "t_from_s,t_to_s,distance_m\n0,100,0.5\n");

  const std::string csv = tmp / "rail.csv";
  ASSERT_EQ(calib({"collect", bag, "-o", csv}, err), 0) << err;
  const std::string csv_bytes = slurp(csv);
  EXPECT_EQ(calib({"fit", csv, "-o", csv, "--degree", "5"}, err), 1);
  EXPECT_THAT(err, HasSubstr("is also an input of this command"));
  EXPECT_EQ(slurp(csv), csv_bytes);

  // A symbolic link and a FIFO are left as they are.
  std::ofstream(tmp / "target.yaml") << "keep me\n";
  fs::create_symlink(tmp / "target.yaml", tmp / "link.yaml");
  EXPECT_EQ(calib({"fit", csv, "-o", tmp / "link.yaml", "--degree", "5"}, err), 1);
  EXPECT_THAT(err, HasSubstr("is a symbolic link"));
  EXPECT_TRUE(fs::is_symlink(tmp / "link.yaml"));
  EXPECT_EQ(slurp(tmp / "target.yaml"), "keep me\n");
  EXPECT_EQ(calib({"collect", bag, "-o", tmp / "link.yaml"}, err), 1);
  EXPECT_TRUE(fs::is_symlink(tmp / "link.yaml"));
  ASSERT_EQ(::mkfifo((tmp / "fifo").c_str(), 0600), 0);
  EXPECT_EQ(calib({"fit", csv, "-o", tmp / "fifo", "--degree", "5"}, err), 1);
  EXPECT_THAT(err, HasSubstr("is a FIFO"));
  EXPECT_EQ(calib({"collect", bag, "-o", tmp / "fifo"}, err), 1);
  EXPECT_TRUE(fs::is_fifo(tmp / "fifo"));

  // Writes that fail part-way (a full disk): the old output stays whole.
  const std::string old_csv = tmp / "old.csv";
  std::ofstream(old_csv) << "t_s,pixel\n";
  with_file_size_limit(4096, [&] { EXPECT_EQ(calib({"collect", bag, "-o", old_csv}, err), 1); });
  EXPECT_EQ(slurp(old_csv), "t_s,pixel\n");
  EXPECT_FALSE(fs::exists(old_csv + ".part"));

  // And a good run still writes.
  ASSERT_EQ(calib({"fit", csv, "-o", tmp / "calib.yaml", "--degree", "5"}, err), 0) << err;
  EXPECT_THAT(slurp(tmp / "calib.yaml"), HasSubstr("format: tinyline_calibration/1"));
  EXPECT_FALSE(fs::exists(tmp / "calib.yaml.part"));
}
