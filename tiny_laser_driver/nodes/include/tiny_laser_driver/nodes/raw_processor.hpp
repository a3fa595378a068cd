// SPDX-License-Identifier: Apache-2.0
// Reprocesses recorded raw scans: subscribes to `raw` (tinyline_msgs/RawScan),
// publishes `scan` (LineScan) and `laser_scan` (LaserScan) exactly as the
// driver would have with the same calibration and optics. Record raw once,
// calibrate again later, replay.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/sensor_msgs/laser_scan.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>

#include <tiny_laser_driver/nodes/scan_messages.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tinyline::tiny_laser_driver {

class RawProcessor : public bus::Node {
 public:
  explicit RawProcessor(bus::NodeOptions options);
  void on_start() override;

  /// Raw scans refused (wrong sizes, impossible fields), each logged.
  [[nodiscard]] std::uint64_t refused() const { return refused_; }

 private:
  void on_raw(const tinyline_msgs::msg::RawScan& m);

  std::string calibration_;
  OpticsParams optics_;
  std::string scan_frame_id_;
  std::unique_ptr<ScanProcessor> processor_;
  std::unique_ptr<ScanMessages> messages_;
  std::string messages_frame_;
  ProcessedScan scan_;
  std::optional<bus::Time> first_stamp_;
  std::optional<bus::Time> prev_stamp_;
  std::uint64_t refused_ = 0;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::LineScan>> scan_pub_;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::LaserScan>> laser_scan_pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::RawScan>> raw_sub_;
};

}  // namespace tinyline::tiny_laser_driver
