// SPDX-License-Identifier: Apache-2.0
// `tinyline calib collect`: a recorded bag (raw scans + the simulator's
// ground-truth topic) -> the calibration data set (data.hpp), one row per
// pixel read-out. Part of the calibration tool library (it reads bags), not
// of the driver's core.
//
// Pairing: each RawScan (tinyline_msgs/RawScan, the driver's or the virtual
// sensor's `raw_scan`) is matched with the ScanTruth (tinyline_msgs/ScanTruth,
// the simulator's `scan_truth`) of the same set: the one whose header stamp is
// nearest, within max_pair_gap_s, and of the same sensor (truth.sensor or its
// frame_id equal to the scan's frame_id, when the bag holds several sensors).
// Each truth is used once. The virtual sensor stamps both with the set's end,
// so they match exactly; the driver and scene_truth stamp independently, a few
// milliseconds apart, well inside one set period (28 ms at 700 pulses).
//
// Rows: every read-out of every pixel whose central ray has a true range and
// is lit by the emitter; masked (dark) pixels, pixels that see nothing and
// mixed pixels (footprint over several surfaces, no single true range) are
// left out and counted. Saturated and starved read-outs are kept: the model's
// validity rule decides. All read-outs of a set share its t_s (the scan's
// stamp since the first scan's), which is how the tool recognises a frame.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <tiny_laser_calibration/data.hpp>
#include <tinyline/common/status.hpp>

namespace tinyline::tiny_laser_calibration {

struct CollectParams {
  std::string raw_topic;          ///< "" = the bag's only RawScan topic
  std::string truth_topic;        ///< "" = the bag's only ScanTruth topic
  std::string sensor;             ///< keep this sensor's sets only ("" = the scans' one frame)
  double max_pair_gap_s = 0.01;   ///< largest stamp difference of a raw scan and its truth [s]
  int pixel_step = 1;             ///< every n-th effective pixel (smaller files)
  bool keep_mixed = false;        ///< also rows of mixed pixels (their truth is the central ray's)
  bool incidence_column = false;  ///< add `incidence_deg` (the ray's angle to the surface normal) as a column
  /// A real sensor on a rail (no truth topic): the tape-measure log of the
  /// target's positions, a CSV `t_from_s,t_to_s,distance_m[,material]` (times in
  /// seconds since the bag's first raw scan, distance from the receiver's lens to
  /// a flat target square to the optical axis). Each pixel's true range is that
  /// distance over the cosine of its ray's angle; scans outside every interval
  /// (the target moving) are left out.
  std::string positions_csv;
  double focal_mm = 3.6;               ///< receiver focal length (the pixels' ray angles)
  double sensor_length_mm = 5.12;      ///< length of the 256 effective pixels
  int pixel_from = -1, pixel_to = -1;  ///< keep only these pixels (-1: every effective one)
};

/// One logged rail position (CollectParams::positions_csv).
struct RailPosition {
  double t_from_s = 0.0, t_to_s = 0.0, distance_m = 0.0;
  std::string material;
  std::size_t line = 0;
};
/// The largest tape-measure log read [bytes] (a line per rail position).
inline constexpr std::uint64_t kMaxRailPositionsBytes = 16u << 20;

/// Reads a tape-measure log (a regular file of at most kMaxRailPositionsBytes);
/// throws CalibrationDataError naming the file, line and column.
std::vector<RailPosition> read_rail_positions(const std::string& path);

struct CollectResult {
  /// Why nothing was collected, naming the bag: the bag's own status when it
  /// cannot be read (OpenFailed, CrcMismatch, Truncated, ...); InvalidArgument
  /// for bad parameters, a bad positions file or a choice left to make (several
  /// sensors or topics); NotFound for a topic, sensor, truth or row not there.
  common::Status status;
  CalibrationDataset data;
  std::string raw_topic, truth_topic;
  std::size_t raw_scans = 0, truths = 0, paired = 0;
  std::size_t unpaired_scans = 0;  ///< raw scans with no truth within max_pair_gap_s
  std::size_t bad_scans = 0;       ///< raw scans that cannot be a set (sizes disagree) or do not decode
  std::size_t other_sensor = 0;    ///< truths of other sensors
  std::size_t dark_pixels = 0, no_range = 0, unlit = 0, mixed = 0;  ///< pixel-sets left out, by reason
  std::size_t between_positions = 0;  ///< raw scans outside every logged rail position (positions_csv)
  std::vector<std::string> notes;
};

/// Reads the bag and builds the data set. Never throws for a bad bag: a status
/// naming the file (and the record's byte offset for a corrupt one).
/// With params.positions_csv: collect_rail_positions().
[[nodiscard]] CollectResult collect_calibration_data(const std::string& bag_path, const CollectParams& params = {});
/// A real sensor's bag (raw scans only) with its tape-measure log (positions_csv).
[[nodiscard]] CollectResult collect_rail_positions(const std::string& bag_path, const CollectParams& params);

}  // namespace tinyline::tiny_laser_calibration
