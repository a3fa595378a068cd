// SPDX-License-Identifier: Apache-2.0
// `tinyline calib fit|diagnose|eval` driven in-process: the outputs
// docs/calibration.md describes, the model the tool writes is the model that is applied,
// and bad input gets a clear error naming the file, line or column.
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <json/json.h>

#include <sys/stat.h>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_calibration/fit.hpp>
#include <tiny_laser_calibration/tool.hpp>

#include "synthetic_sensor.hpp"

namespace fs = std::filesystem;
namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;
using ::testing::HasSubstr;

namespace {

class CalibTool : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("tinyline_calib_tool_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    env_.python = TINYLINE_VENV_PYTHON;
    env_.plot_script = std::string(TINYLINE_SOURCE_DIR) + "/scripts/plots/calib_report.py";
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  std::string write_file(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }

  // A rail with the supply-voltage effect, so --discover has something to find.
  std::string rail_csv(bool with_effect = true) const {
    tt::SyntheticSensor s;
    s.effects.supply_voltage = with_effect;
    s.effects.supply_column = true;
    auto plan = tt::default_rail();
    plan.pixels.clear();
    for (int px = 8; px < 264; px += 16) plan.pixels.push_back(px);
    const auto data = tt::simulate_rail(s, plan);
    const std::string p = path(with_effect ? "rail.csv" : "rail_null.csv");
    cal::write_calibration_csv(data, p);
    return p;
  }

  int run(const std::vector<std::string>& args) {
    out_.str("");
    err_.str("");
    return cal::run_calib_command(args, out_, err_, env_);
  }

  fs::path dir_;
  cal::CalibToolEnv env_;
  std::ostringstream out_, err_;
};

std::string slurp(const std::string& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Json::Value parse_json(const std::string& text) {
  Json::Value v;
  std::string errors;
  std::istringstream in(text);
  EXPECT_TRUE(Json::parseFromStream(Json::CharReaderBuilder(), in, &v, &errors)) << errors << "\n" << text;
  return v;
}

}  // namespace

TEST_F(CalibTool, FitDiscoverWritesModelSummaryAndReportWithPlots) {
  const auto csv = rail_csv();
  const auto yaml = path("calib.yaml");
  const auto report = path("report");
  ASSERT_EQ(run({"fit", csv, "-o", yaml, "--discover", "--report", report}), 0) << err_.str();
  EXPECT_THAT(out_.str(), HasSubstr("effect: supply_v (smooth)"));
  EXPECT_THAT(out_.str(), HasSubstr("wrote " + yaml));
  const Json::Value summary = parse_json(slurp(report + "/summary.json"));
  ASSERT_EQ(summary["effects"].size(), 1u);
  EXPECT_EQ(summary["effects"][0]["covariate"].asString(), "supply_v");
  EXPECT_EQ(summary["effects"][0]["form"].asString(), "smooth");
  EXPECT_TRUE(summary["acceptance"]["z_threshold"].isDouble());
  EXPECT_FALSE(summary["rounds"].empty());
  // The held-out figures in summary.json are JSON numbers, the effect's after below its before.
  ASSERT_TRUE(summary["rmse_before_m"].isDouble() && summary["rmse_after_m"].isDouble());
  EXPECT_LT(summary["rmse_after_m"].asDouble(), 0.8 * summary["rmse_before_m"].asDouble());
  const std::string md = slurp(report + "/report.md");
  EXPECT_THAT(md, HasSubstr("| supply_v | smooth |"));
  EXPECT_THAT(md, HasSubstr("![Fitted curve"));
  for (const char* png : {"curve.png", "error_by_distance.png", "residual_supply_v.png", "residual_pixel.png",
                          "residual_t_s.png", "residual_pulses.png", "residual_amplitude.png",
                          "residual_amplitude_per_pulse.png", "residual_ratio.png", "residual_temperature_c.png"}) {
    EXPECT_TRUE(fs::exists(report + "/" + png)) << png;
    EXPECT_THAT(md, HasSubstr(std::string("(") + png + ")")) << png;
  }
  const auto model = tl::CalibrationModel::load(yaml);
  ASSERT_EQ(model.impl().terms.size(), 1u);
  EXPECT_EQ(model.extra_covariates(), std::vector<std::string>{"supply_v"});
}

TEST_F(CalibTool, EvalPrintsTheIssuesJsonOfTheModelTheToolWrote) {
  const auto csv = rail_csv();
  const auto yaml = path("calib.yaml");
  ASSERT_EQ(run({"fit", csv, "-o", yaml, "--discover"}), 0) << err_.str();
  ASSERT_EQ(run({"eval", csv, "--calib", yaml}), 0) << err_.str();
  const std::string json = out_.str();
  EXPECT_EQ(json.find('\n'), json.size() - 1) << "one line: " << json;
  const Json::Value v = parse_json(json);
  for (const char* key : {"n", "rmse_m", "bias_m", "p95_abs_m"}) EXPECT_TRUE(v[key].isNumeric()) << key << json;
  // The same figures as the loaded model applied read-out by read-out (what the driver does).
  const auto model = tl::CalibrationModel::load(yaml);
  const auto data = cal::read_calibration_csv(csv);
  const auto rows = cal::select_readouts(data, {}, model.validity(), cal::ReadoutSelection::kDriver);
  const auto readouts = cal::readouts_for_model(data, model);
  double sum2 = 0.0;
  std::size_t n = 0;
  for (std::size_t i : rows) {
    const double d = model.distance_m(readouts[i]);
    if (std::isnan(d)) continue;
    sum2 += (d - data.distance_m[i]) * (d - data.distance_m[i]);
    ++n;
  }
  EXPECT_EQ(v["n"].asUInt64(), n);
  EXPECT_NEAR(v["rmse_m"].asDouble(), std::sqrt(sum2 / static_cast<double>(n)), 1e-12);
  EXPECT_LT(v["rmse_m"].asDouble(), 0.01);
  EXPECT_LT(std::abs(v["bias_m"].asDouble()), 0.002);
  // Every valid read-out instead of the driver's choice: more of them.
  ASSERT_EQ(run({"eval", csv, "--calib", yaml, "--select", "all"}), 0) << err_.str();
  EXPECT_GT(parse_json(out_.str())["n"].asUInt64(), n);
}

TEST_F(CalibTool, FitWithoutDiscoverWritesTheDeclaredModel) {
  const auto csv = rail_csv();
  const auto yaml = path("declared.yaml");
  ASSERT_EQ(run({"fit", csv, "-o", yaml, "--degree", "3", "--leakage", "0,0.005", "--rsen", "fixed"}), 0) << err_.str();
  const auto model = tl::CalibrationModel::load(yaml);
  EXPECT_EQ(model.impl().poly_m.size(), 4u);
  EXPECT_TRUE(model.impl().terms.empty());
  EXPECT_TRUE(model.impl().sensitivity_ratio_per_pixel.empty());
  EXPECT_EQ(model.impl().leakage_per_pulse, 0.005);
  EXPECT_THAT(out_.str(), ::testing::Not(HasSubstr("held-out")));
}

TEST_F(CalibTool, DiagnoseNamesTheColumnTheCalibrationMisses) {
  const auto null_csv = rail_csv(false);
  const auto csv = rail_csv(true);
  const auto yaml = path("calib.yaml");
  ASSERT_EQ(run({"fit", null_csv, "-o", yaml}), 0) << err_.str();
  const auto report = path("diag");
  ASSERT_EQ(run({"diagnose", csv, "--calib", yaml, "--report", report}), 0) << err_.str();
  EXPECT_THAT(out_.str(), HasSubstr("effect: supply_v"));
  EXPECT_EQ(parse_json(slurp(report + "/summary.json"))["command"].asString(), "diagnose");
  EXPECT_TRUE(fs::exists(report + "/report.md"));
  EXPECT_TRUE(fs::exists(report + "/residual_supply_v.png"));
}

TEST_F(CalibTool, ReportWithoutPythonStillWritesSummaryAndSaysWhy) {
  env_.python = "/nonexistent/python";
  const auto csv = rail_csv();
  ASSERT_EQ(run({"fit", csv, "-o", path("c.yaml"), "--report", path("r")}), 0) << err_.str();
  EXPECT_THAT(err_.str(), HasSubstr("warning: cannot run /nonexistent/python"));
  EXPECT_TRUE(fs::exists(path("r/summary.json")));
  EXPECT_THAT(slurp(path("r/report.md")), HasSubstr("Plots were not drawn: cannot run /nonexistent/python"));
}

// Every text input of the tool is read only if it is a regular file: a FIFO
// used to block `fit`, `eval` and `collect --positions` for ever.
TEST_F(CalibTool, AFifoOrADeviceAsAnInputIsRefusedNamingItWithExitCode1) {
  const std::string fifo = path("pipe.csv");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto csv = rail_csv(false);
  ASSERT_EQ(run({"fit", csv, "-o", path("c.yaml")}), 0) << err_.str();
  for (const std::string& input : {fifo, std::string("/dev/zero")}) {
    EXPECT_EQ(run({"fit", input, "-o", path("x.yaml")}), 1);
    EXPECT_THAT(err_.str(), HasSubstr("data file '" + input + "' is a"));
    EXPECT_EQ(run({"eval", input, "--calib", path("c.yaml")}), 1);
    EXPECT_THAT(err_.str(), HasSubstr("data file '" + input + "' is a"));
    EXPECT_EQ(run({"eval", csv, "--calib", input}), 1);
    EXPECT_THAT(err_.str(), HasSubstr("calibration file '" + input + "' is a"));
    EXPECT_EQ(run({"measured", "--data", input}), 1);
    EXPECT_THAT(err_.str(), HasSubstr("measured figures '" + input + "' is a"));
    try {
      (void)cal::read_rail_positions(input);
      ADD_FAILURE() << "read the positions from " << input;
    } catch (const cal::CalibrationDataError& e) {
      EXPECT_THAT(e.what(), HasSubstr("rail positions '" + input + "' is a"));
    }
  }
  EXPECT_FALSE(fs::exists(path("x.yaml")));
}

TEST_F(CalibTool, BadInputGetsAClearErrorAndExitCode) {
  const std::string header = "t_s,pixel,pulses,a,b,temperature_c,distance_m\n";
  // Missing file.
  EXPECT_EQ(run({"eval", path("none.csv"), "--calib", path("none.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("none.yaml': cannot open: No such file"));
  EXPECT_EQ(run({"fit", path("none.csv"), "-o", path("x.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("none.csv': cannot open: No such file"));
  // Missing column.
  const auto no_col = write_file("nocol.csv", "t_s,pixel,a,b,temperature_c,distance_m\n0,10,50,50,40,0.5\n");
  EXPECT_EQ(run({"fit", no_col, "-o", path("x.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("nocol.csv:1: missing required column 'pulses'"));
  // Non-numeric cell.
  const auto bad_cell = write_file("cell.csv", header + "0,10,100,50,50,40,0.5\n0,10,100,5O,50,40,0.5\n");
  EXPECT_EQ(run({"fit", bad_cell, "-o", path("x.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("cell.csv:3: column 'a': '5O' is not a number"));
  // Empty file.
  const auto empty = write_file("empty.csv", "");
  EXPECT_EQ(run({"fit", empty, "-o", path("x.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("empty.csv: empty file"));
  // Every row invalid.
  const auto invalid = write_file("invalid.csv", header + "0,10,100,240,50,40,0.5\n0,11,100,2,3,40,0.5\n");
  EXPECT_EQ(run({"fit", invalid, "-o", path("x.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("no valid read-outs among 2 rows"));
  EXPECT_THAT(err_.str(), HasSubstr("1 saturated"));
  EXPECT_FALSE(fs::exists(path("x.yaml")));  // nothing half-written
  // Usage errors: exit 2 with the reason.
  EXPECT_EQ(run({"fit", invalid}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("--output is required"));
  EXPECT_EQ(run({"fit", invalid, "-o", path("x.yaml"), "--degre", "3"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("--degre"));
  EXPECT_EQ(run({"fit", invalid, "-o", path("x.yaml"), "--degree", "13"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("--degree: 13 is outside 1..12"));
  EXPECT_EQ(run({"fit", invalid, "-o", path("x.yaml"), "--leakage", "1,x"}), 2);
  EXPECT_THAT(err_.str(), HasSubstr("'1,x' is not 'fit' or OFFSET,PER_PULSE"));
  EXPECT_EQ(run({"frobnicate"}), 2);
  EXPECT_EQ(run({}), 2);
  EXPECT_EQ(run({"--help"}), 0);
  EXPECT_THAT(out_.str(), HasSubstr("Usage: tinyline calib"));
  for (const char* sub : {"fit", "diagnose", "eval", "collect", "measured"}) EXPECT_THAT(out_.str(), HasSubstr(sub));
  // A calibration file that is not one.
  const auto bad_yaml =
      write_file("bad.yaml", "format: tinyline_calibration/1\npolynomial: {coefficients_m: [1, x]}\n");
  EXPECT_EQ(run({"eval", invalid, "--calib", bad_yaml}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("bad.yaml:2: field 'polynomial.coefficients_m[1]'"));
}

// Regression: `fit data.csv.part -o data.csv` deleted its input (the writer
// took "<output>.part" for its own temporary).
TEST_F(CalibTool, FitNeverTouchesAnInputNamedLikeItsTemporary) {
  const auto csv = rail_csv(false);
  const auto part = path("data.csv.part");
  fs::copy_file(csv, part);
  const std::string before = slurp(part);
  EXPECT_EQ(run({"fit", part, "-o", path("data.csv")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr(part + " is an input of this command"));
  EXPECT_EQ(slurp(part), before);
  EXPECT_FALSE(fs::exists(path("data.csv")));
}

// Regression: `fit -o OUT --report BAD` replaced OUT, then failed on the report.
TEST_F(CalibTool, AFitThatFailsOnItsReportLeavesTheModelAsItWas) {
  const auto csv = rail_csv(false);
  const auto yaml = write_file("calib.yaml", "the user's model\n");
  const auto not_a_dir = write_file("report", "a file, not a directory\n");
  EXPECT_EQ(run({"fit", csv, "-o", yaml, "--report", not_a_dir}), 1);
  EXPECT_THAT(err_.str(), HasSubstr(not_a_dir + ": cannot create the report directory"));
  EXPECT_EQ(slurp(yaml), "the user's model\n");
  fs::create_directories(path("r"));
  fs::create_symlink(csv, path("r/curve.csv"));  // a report file it must not replace
  EXPECT_EQ(run({"fit", csv, "-o", yaml, "--report", path("r")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("curve.csv' is a symbolic link"));
  EXPECT_EQ(slurp(yaml), "the user's model\n");
  EXPECT_FALSE(fs::exists(path("r/summary.json")));
  EXPECT_FALSE(fs::exists(path("r/summary.json.part")));
}

// Regression: a truth distance of 1e22 m was fitted, and the model written
// was one the driver's own loader refuses.
TEST_F(CalibTool, AnAbsurdTruthDistanceIsRefusedNamingTheLine) {
  const std::string header = "t_s,pixel,pulses,a,b,temperature_c,distance_m\n";
  const auto csv = write_file("far.csv", header + "0,10,100,50,50,40,0.5\n0,10,100,50,50,40,1e22\n");
  EXPECT_EQ(run({"fit", csv, "-o", path("far.yaml")}), 1);
  EXPECT_THAT(err_.str(), HasSubstr("far.csv:3: column 'distance_m': 1e+22 m is beyond any target"));
  EXPECT_FALSE(fs::exists(path("far.yaml")));
}
