// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/nodes/raw_processor.hpp>

#include <tinyline/bus/param_table.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>
#include <tiny_laser_driver/param_tables.hpp>

namespace tinyline::tiny_laser_driver {

RawProcessor::RawProcessor(bus::NodeOptions options) : Node(std::move(options)) {
  const DriverParams d;  // the same defaults as the driver
  calibration_ = declare_parameter("calibration", d.calibration,
                                   "calibration YAML, public:NAME, or default (the simulated sensor's)",
                                   calibration_file_constraints());
  bus::declare_params(*this, optics_);  // the table: tiny_laser_driver/param_tables.hpp
  require_valid(optics_.validate().within("optics"));
  scan_frame_id_ = declare_parameter("scan_frame_id", d.scan_frame_id,
                                     "frame of the LaserScan; empty: the raw scan's frame_id + '_scan'");
  scan_pub_ = create_publisher<tinyline_msgs::msg::LineScan>("scan", bus::QoS::sensor_data());
  laser_scan_pub_ = create_publisher<sensor_msgs::msg::LaserScan>("laser_scan", bus::QoS::sensor_data());
  raw_sub_ = create_subscription<tinyline_msgs::msg::RawScan>(
      "raw", bus::QoS::keep_last(10), [this](const tinyline_msgs::msg::RawScan& m) { on_raw(m); });
}

void RawProcessor::on_start() {
  if (!processor_) processor_ = std::make_unique<ScanProcessor>(load_calibration(calibration_), optics_);
}

void RawProcessor::on_raw(const tinyline_msgs::msg::RawScan& m) {
  if (!processor_) on_start();
  std::string why;
  const auto set = from_raw_scan(m, &why);
  if (!set) {
    ++refused_;
    logger().error("raw scan {} refused: {}", m.set_index, why);
    return;
  }
  if (!messages_ || messages_frame_ != m.header.frame_id) {
    messages_frame_ = m.header.frame_id;
    messages_ = std::make_unique<ScanMessages>(*processor_, m.header.frame_id,
                                               scan_frame_id_.empty() ? m.header.frame_id + "_scan" : scan_frame_id_);
  }
  const bus::Time stamp = bus::Time::from_msg(m.header.stamp);
  if (!first_stamp_) first_stamp_ = stamp;
  processor_->process(*set, (stamp - *first_stamp_).count() * 1e-9, scan_);
  const double period = prev_stamp_ ? (stamp - *prev_stamp_).count() * 1e-9 : 0.0;
  prev_stamp_ = stamp;
  scan_pub_->publish(messages_->line(scan_, m.set_index, stamp, m.temperature_c));
  laser_scan_pub_->publish(messages_->laser(scan_, stamp, period));
}

}  // namespace tinyline::tiny_laser_driver
