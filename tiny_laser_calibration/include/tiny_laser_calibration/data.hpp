// SPDX-License-Identifier: Apache-2.0
// A calibration data set: one row per pixel read-out with the true distance.
// CSV columns, in any order:
//   t_s,pixel,pulses,a,b,temperature_c,distance_m   required
//   material                                        optional text
//   anything else                                   further numeric covariates
// Blank lines and lines starting with '#' are skipped.
#pragma once

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/calibration_impl.hpp>

namespace tinyline::tiny_laser_calibration {

// The model this package fits is the driver's (tiny_laser_driver/
// calibration.hpp, calibration_impl.hpp): the driver applies what the fit
// writes. Its vocabulary, by name here.
using tiny_laser_driver::acts_on_charges;
using tiny_laser_driver::AmplitudeReference;
using tiny_laser_driver::builtin_covariates;
using tiny_laser_driver::CalibrationEvaluation;
using tiny_laser_driver::CalibrationFitInfo;
using tiny_laser_driver::CalibrationModel;
using tiny_laser_driver::CalibrationTerm;
using tiny_laser_driver::Covariate;
using tiny_laser_driver::covariate_from_name;
using tiny_laser_driver::covariate_name;
using tiny_laser_driver::covariate_parameter;
using tiny_laser_driver::Readout;
using tiny_laser_driver::term_form_from_string;
using tiny_laser_driver::TermForm;
using tiny_laser_driver::to_string;
using tiny_laser_driver::ValidityRule;

/// Bad calibration data; what() names the file, the line and the column.
class CalibrationDataError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct CalibrationDataset {
  std::string source;                    ///< file name, for messages
  std::vector<std::string> extra_names;  ///< further numeric columns, in file order
  std::vector<Readout> readouts;         ///< Readout::extra holds the extra columns in extra_names order
  std::vector<double> distance_m;        ///< ground truth along the pixel's ray [m]
  bool has_material = false;
  std::vector<std::string> materials;  ///< distinct material names
  std::vector<int> material;           ///< per row: index into materials, -1 without a material column
  std::vector<std::size_t> line;       ///< per row: 1-based line in the file (0 if not from a file)

  [[nodiscard]] std::size_t size() const { return readouts.size(); }
  [[nodiscard]] bool empty() const { return readouts.empty(); }
  /// Appends a row (material "" when the set has none).
  void add(Readout r, double distance, const std::string& material_name = {}, std::size_t line_no = 0);
  /// Index of an extra column, or -1.
  [[nodiscard]] int extra_index(std::string_view name) const;
  /// Rows `rows` of this set, in that order.
  [[nodiscard]] CalibrationDataset subset(const std::vector<std::size_t>& rows) const;
};

inline constexpr const char* kRequiredCalibrationColumns[] = {"t_s", "pixel",         "pulses",    "a",
                                                              "b",   "temperature_c", "distance_m"};

/// The largest calibration CSV read [bytes]: about 15 million rows.
inline constexpr std::uint64_t kMaxCalibrationCsvBytes = std::uint64_t{1} << 30;

/// Reads a CSV file: only a regular file (a FIFO or a device is refused, not
/// waited on or read without end) of at most kMaxCalibrationCsvBytes. Throws
/// CalibrationDataError naming file, line and column (missing column,
/// non-numeric or non-finite cell, wrong cell count, pixel outside 0-271,
/// pulses below 1, distance not positive, empty file).
CalibrationDataset read_calibration_csv(const std::string& path);
CalibrationDataset parse_calibration_csv(std::string_view text, const std::string& source_name);

/// Writes the set in the same format (required columns, material if present, extras).
void write_calibration_csv(const CalibrationDataset& data, std::ostream& out);
void write_calibration_csv(const CalibrationDataset& data, const std::string& path);

/// Per row, the id (0..n-1, in time order) of its frame: rows with the same t_s
/// (and the same `session`, when the set has that column: each session's t_s
/// starts at its own power-on).
std::vector<int> frame_ids(const CalibrationDataset& data);

/// Name of the MCU temperature low-pass filtered with time constant tau
/// ("temperature_c_lp120s"): what a part that warms more slowly than the MCU
/// (the MOSFET driver, 3.3.4) follows. Rounded to whole seconds.
std::string lagged_temperature_name(double tau_s);
/// tau of such a name; 0 when `name` is not one.
double lagged_temperature_tau(std::string_view name);
/// The set with a column per time constant: the temperature low-pass filtered
/// over each session's frames in time order (started at its first reading).
/// Existing columns of that name are kept as they are.
CalibrationDataset with_lagged_temperature(const CalibrationDataset& data, const std::vector<double>& taus_s);
/// with_lagged_temperature() for the lagged-temperature names among `names` (a
/// model's extra covariates) that the set lacks.
CalibrationDataset with_derived_covariates(const CalibrationDataset& data, const std::vector<std::string>& names);
/// Per row, the id of its target-distance group: the median true distance of
/// the row's frame, in bins of `bin_m`. On a calibration rail every frame at one
/// rail position lands in one group, whatever the pixel (rays off the axis are
/// longer than the target distance). Ids are in increasing distance.
std::vector<int> target_distance_groups(const CalibrationDataset& data, double bin_m = 0.005);

/// Read-outs of `data` with Readout::extra rearranged into `model`'s
/// extra_covariates() order (NaN for a covariate the data lacks).
std::vector<Readout> readouts_for_model(const CalibrationDataset& data, const CalibrationModel& model);

}  // namespace tinyline::tiny_laser_calibration
