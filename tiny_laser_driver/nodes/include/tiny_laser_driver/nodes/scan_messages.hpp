// SPDX-License-Identifier: Apache-2.0
// Conversions between the driver's core types and its messages, shared by the
// driver and the raw-scan processor (so a recorded RawScan reprocessed later
// gives byte for byte the LineScan the driver published live).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tinyline/bus/time.hpp>
#include <tinyline/msg/sensor_msgs/laser_scan.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>

#include <tiny_laser_driver/protocol.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tinyline::tiny_laser_driver {

/// RawScan of a set, as transmitted.
[[nodiscard]] std::unique_ptr<tinyline_msgs::msg::RawScan> to_raw_scan(const RawSet& set, bus::Time stamp,
                                                                       const std::string& frame_id);

/// The set a RawScan carries, or nullopt with `why` when the message cannot
/// be one (pixel count, array lengths, pulses).
[[nodiscard]] std::optional<RawSet> from_raw_scan(const tinyline_msgs::msg::RawScan& m, std::string* why);

/// Builds LineScan and LaserScan messages for one sensor's optics.
class ScanMessages {
 public:
  ScanMessages(const ScanProcessor& processor, std::string frame_id, std::string scan_frame_id);

  [[nodiscard]] std::unique_ptr<tinyline_msgs::msg::LineScan> line(const ProcessedScan& scan, std::uint32_t index,
                                                                   bus::Time stamp, float temperature_c) const;
  /// REP 117 ranges: the distance, +inf where nothing came back (too dark),
  /// NaN where the reading is unusable; intensities: (a + b) per pulse.
  [[nodiscard]] std::unique_ptr<sensor_msgs::msg::LaserScan> laser(const ProcessedScan& scan, bus::Time stamp,
                                                                   double scan_time_s) const;
  /// The line as an organized cloud in frame_id: one point per pixel (height
  /// 1, width 272, the dark pixels too), fields x y z intensity (float32 in
  /// the host's byte order, as is_bigendian says), each point distance_m
  /// along its pixel's ray; x y z NaN where the pixel has no valid distance
  /// (is_dense false): the LaserScan's NaN and +inf alike.
  [[nodiscard]] std::unique_ptr<sensor_msgs::msg::PointCloud2> cloud(const ProcessedScan& scan, bus::Time stamp) const;
  [[nodiscard]] const std::string& frame_id() const { return frame_id_; }

 private:
  std::vector<float> angles_;
  UniformScanLayout layout_;
  std::string frame_id_;
  std::string scan_frame_id_;
};

}  // namespace tinyline::tiny_laser_driver
