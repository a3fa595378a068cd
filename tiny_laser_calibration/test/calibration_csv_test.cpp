// SPDX-License-Identifier: Apache-2.0
// The calibration CSV reader: the format of data.hpp and its bad-input errors.
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <sys/stat.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tiny_laser_calibration/data.hpp>

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
using ::testing::HasSubstr;

namespace {

std::string expect_error(const std::string& csv) {
  try {
    (void)cal::parse_calibration_csv(csv, "data.csv");
  } catch (const cal::CalibrationDataError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for:\n" << csv;
  return {};
}

const char* kHeader = "t_s,pixel,pulses,a,b,temperature_c,distance_m";

}  // namespace

TEST(CalibrationCsv, ReadsRequiredMaterialAndExtraColumns) {
  const std::string csv =
      "# rail run 1\r\n"
      "distance_m,t_s,material,pixel,pulses,a,b,temperature_c,humidity\r\n"
      "0.5,1.25,white_paper,100,200,120.5,60.25,41.3,55\r\n"
      "\r\n"
      "0.75,1.5,\"cloth, blue\",101,700,80,90,41.4,56.5\r\n";
  const auto d = cal::parse_calibration_csv(csv, "data.csv");
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d.extra_names, std::vector<std::string>{"humidity"});
  ASSERT_TRUE(d.has_material);
  EXPECT_EQ(d.materials[static_cast<std::size_t>(d.material[1])], "cloth, blue");
  EXPECT_EQ(d.readouts[0].pixel, 100);
  EXPECT_EQ(d.readouts[0].pulses, 200);
  EXPECT_DOUBLE_EQ(d.readouts[0].a, 120.5);
  EXPECT_DOUBLE_EQ(d.readouts[0].b, 60.25);
  EXPECT_DOUBLE_EQ(d.readouts[0].t_s, 1.25);
  EXPECT_DOUBLE_EQ(d.readouts[0].temperature_c, 41.3);
  EXPECT_DOUBLE_EQ(d.distance_m[1], 0.75);
  EXPECT_EQ(d.readouts[1].extra, std::vector<double>{56.5});
  EXPECT_EQ(d.line[0], 3u);
  EXPECT_EQ(d.line[1], 5u);
}

TEST(CalibrationCsv, WriteThenReadIsIdentity) {
  cal::CalibrationDataset d;
  d.source = "mem";
  d.has_material = true;
  d.extra_names = {"supply_v"};
  tl::Readout r;
  r.t_s = 0.1;
  r.pixel = 8;
  r.pulses = 20;
  r.a = 1.0 / 3.0;
  r.b = 17.25;
  r.temperature_c = 30.1;
  r.extra = {4.95};
  d.add(r, 0.123456789, "ic_foam");
  std::stringstream ss;
  cal::write_calibration_csv(d, ss);
  const auto back = cal::parse_calibration_csv(ss.str(), "mem");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back.readouts[0].a, r.a);
  EXPECT_EQ(back.distance_m[0], 0.123456789);
  EXPECT_EQ(back.materials[0], "ic_foam");
  EXPECT_EQ(back.readouts[0].extra, r.extra);
}

TEST(CalibrationCsv, MissingColumnIsNamed) {
  EXPECT_THAT(expect_error("t_s,pixel,a,b,temperature_c,distance_m\n0,1,2,3,4,5\n"),
              HasSubstr("data.csv:1: missing required column 'pulses'"));
}

TEST(CalibrationCsv, NonNumericCellNamesLineAndColumn) {
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,100,200,1,2,40,0.5\n0,100,200,x1,2,40,0.5\n"),
              HasSubstr("data.csv:3: column 'a': 'x1' is not a number"));
  EXPECT_THAT(expect_error(std::string(kHeader) + ",humidity\n0,100,200,1,2,40,0.5,\n"),
              HasSubstr("data.csv:2: column 'humidity': '' is not a number"));
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,100,200,nan,2,40,0.5\n"),
              HasSubstr("data.csv:2: column 'a': 'nan' is not finite"));
}

TEST(CalibrationCsv, EmptyAndHeaderOnlyFiles) {
  EXPECT_THAT(expect_error(""), HasSubstr("data.csv: empty file"));
  EXPECT_THAT(expect_error("# only a comment\n\n"), HasSubstr("data.csv: empty file"));
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n"), HasSubstr("data.csv: no data rows"));
}

TEST(CalibrationCsv, RangeAndShapeErrors) {
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,300,200,1,2,40,0.5\n"),
              HasSubstr("data.csv:2: column 'pixel': '300' is not an integer in [0, 271]"));
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,10,0,1,2,40,0.5\n"),
              HasSubstr("column 'pulses': '0' is not an integer"));
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,10,20.5,1,2,40,0.5\n"),
              HasSubstr("column 'pulses': '20.5' is not an integer"));
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,10,20,1,2,40,-0.5\n"),
              HasSubstr("data.csv:2: column 'distance_m': -0.5 is not a positive distance"));
  EXPECT_THAT(expect_error(std::string(kHeader) + "\n0,10,20,1,2,40\n"),
              HasSubstr("data.csv:2: expected 7 cells (one per header column), found 6"));
  EXPECT_THAT(expect_error("t_s,pixel,pixel,pulses,a,b,temperature_c,distance_m\n"),
              HasSubstr("column 'pixel' appears twice"));
  EXPECT_THAT(expect_error(std::string(kHeader) + ",material\n0,10,20,1,2,40,0.5,\"open\n"),
              HasSubstr("data.csv:2: unterminated quoted cell"));
  EXPECT_THAT(expect_error(std::string("\x89PNG\r\n\x1a\n\0\0\0", 11)), HasSubstr("data.csv:"));
}

TEST(CalibrationCsv, UnreadableFile) {
  try {
    (void)cal::read_calibration_csv("/nonexistent/data.csv");
    FAIL();
  } catch (const cal::CalibrationDataError& e) {
    EXPECT_THAT(e.what(), HasSubstr("data file '/nonexistent/data.csv': cannot open"));
  }
}

// A FIFO used to block the read for ever, /dev/zero to be read until memory ran out.
TEST(CalibrationCsv, AFifoOrADeviceIsRefusedNamingItInsteadOfReadForEver) {
  const auto dir = std::filesystem::temp_directory_path() / ("calib_csv_fifo_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string fifo = (dir / "data.csv").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const auto& [path, kind] :
       {std::pair{fifo, "is a FIFO"}, std::pair{std::string("/dev/zero"), "is a character device"}}) {
    try {
      (void)cal::read_calibration_csv(path);
      ADD_FAILURE() << "read " << path;
    } catch (const cal::CalibrationDataError& e) {
      EXPECT_THAT(e.what(), HasSubstr("data file '" + path + "' " + kind + ", not a regular file"));
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(CalibrationCsv, MangledBytesGiveEitherDataOrAClearError) {
  const std::string good =
      "t_s,pixel,pulses,a,b,temperature_c,distance_m,material,humidity\n"
      "0.5,100,200,120.5,60.25,41.3,0.5,white_paper,55\n"
      "0.5,101,700,80,90,41.4,0.75,\"cloth, blue\",56.5\n";
  std::mt19937 rng(5);
  std::size_t parsed = 0, refused = 0;
  for (int i = 0; i < 4000; ++i) {
    std::string s = good;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = rng() % (s.size() + 1);
      switch (rng() % 3) {
        case 0:
          if (at < s.size()) s[at] = static_cast<char>(rng() % 256);
          break;
        case 1: s.insert(at, 1, static_cast<char>(rng() % 256)); break;
        default:
          if (at < s.size()) s.erase(at, 1);
          break;
      }
    }
    try {
      const auto d = cal::parse_calibration_csv(s, "m.csv");
      for (std::size_t r = 0; r < d.size(); ++r) {
        ASSERT_TRUE(std::isfinite(d.readouts[r].a) && std::isfinite(d.distance_m[r]) && d.distance_m[r] > 0);
        ASSERT_GE(d.readouts[r].pixel, 0);
        ASSERT_LE(d.readouts[r].pixel, 271);
      }
      ++parsed;
    } catch (const cal::CalibrationDataError& e) {
      ASSERT_THAT(e.what(), HasSubstr("m.csv"));
      ++refused;
    }
  }
  EXPECT_GT(parsed, 100u);
  EXPECT_GT(refused, 1000u);
}
