// SPDX-License-Identifier: Apache-2.0
// The tiny laser driver node: reads the sensor's byte stream (serial port,
// usb:SERIAL, sim:SCENE.yaml, mem:NAME), parses raw and distance frames
// alike (either firmware, without being told), turns repeated frames into one
// fresh measurement each, processes raw sets with the calibration model, and
// publishes
//
//   raw          tinyline_msgs/RawScan           every read-out, as sent (raw mode)
//   scan         tinyline_msgs/LineScan          calibrated distance, intensity, reflectance, status per pixel
//   laser_scan   sensor_msgs/LaserScan           for standard viewers (frame scan_frame_id, see docs/driver.md)
//   /diagnostics diagnostic_msgs/DiagnosticArray link state, frame rate, drops by reason, saturated share,
//                                                temperature, link utilisation
//
// and subscribes to `laser_command` (tinyline_msgs/LaserCommand, the
// multi-sensor sequencer's on/off orders).
//
// The I/O thread starts in on_start() and stops in on_stop(). When the device
// goes away it keeps running: it reports the state, and reopens the port with
// a backoff (reconnect_min_s doubling up to reconnect_max_s) until the device
// is back. A set cut by a disconnect is never published.
//
// Timestamps: host receive time of a frame's last byte minus the frame's
// transmission time at the link rate (a set: its last frame, the read-out with
// the most pulses); a measurement repeated on the wire keeps the stamp of its
// first arrival.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/diagnostic_msgs/diagnostic_array.hpp>
#include <tinyline/msg/sensor_msgs/laser_scan.hpp>
#include <tinyline/msg/tinyline_msgs/laser_command.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>

#include <tiny_laser_driver/io/port.hpp>
#include <tiny_laser_driver/nodes/scan_messages.hpp>
#include <tiny_laser_driver/protocol.hpp>
#include <tiny_laser_driver/scan_processor.hpp>
#include <tiny_laser_driver/stream_health.hpp>

namespace tinyline::tiny_laser_driver {

/// The driver's settings; node parameters take their defaults from here.
struct DriverParams {
  std::string port = "/dev/ttyUSB0";  ///< /dev/..., usb:SERIAL, sim:SCENE.yaml, mem:NAME
  /// The frames expected: "auto" (either), "raw" (the host computes distance)
  /// or "distance" (the firmware does). Only checked and reported: frames of
  /// either kind are always read.
  std::string mode = "auto";
  double baud = 2'000'000;         ///< link rate [bit/s]
  int readouts_per_set = 5;        ///< raw mode: frames per set
  OpticsParams optics;             ///< focal_mm, sensor_length_mm
  std::string frame_id = "laser";  ///< sensor frame: z forward, x along the line
  std::string scan_frame_id;       ///< LaserScan frame (x = sensor z, y = sensor x); "" = frame_id + "_scan"
  std::string calibration =
      "default";                  ///< calibration YAML, "public:K" (R J S K T), or "default" (the simulated sensor's)
  double distance_unit_m = 1e-4;  ///< distance frames: the firmware's unit [m] (the published firmware: 0.1 mm)
  int stale_after = 20;           ///< fresh measurements a pixel may stay unchanged while its neighbours change
  std::string sensor_name;        ///< name in LaserCommand.sensors; "" = the node's name
  int sequence_slot = -1;         ///< sequence mode slot (>= 0: laser off until a LaserCommand enables the slot)
  bool send_stream_mode = false;  ///< send the 0x11 stream-mode command on connect (tinyline extension)
  double reconnect_min_s = 0.05;  ///< first retry after a disconnect [s]
  double reconnect_max_s = 0.5;   ///< longest wait between retries [s] (keeps resume-after-replug under 1 s)
  double diagnostics_period_s = 1.0;  ///< [s]
  double stall_timeout_s = 1.0;       ///< connected but no complete frame for this long: WARN [s]
  bool threaded = true;               ///< run the I/O thread (false: the embedding code calls pump())
  bool publish_raw = true;            ///< publish RawScan (raw mode)
  bool publish_cloud = false;         ///< publish the line as sensor_msgs/PointCloud2 on `cloud`
};

/// What the link is doing, for diagnostics and tests (a copy, thread-safe).
struct DriverStatus {
  bool connected = false;
  std::string link;  ///< the open stream, e.g. "/dev/ttyUSB0 at 2000000 baud"
  io::IoError last_error = io::IoError::kNone;
  std::string last_error_message;
  std::uint64_t connects = 0;     ///< successful opens
  std::uint64_t disconnects = 0;  ///< streams lost while open
  std::uint64_t open_failures = 0;
  std::uint64_t scans_published = 0;  ///< LineScans
  std::uint64_t bytes = 0;            ///< bytes received
  std::uint64_t commands_sent = 0;
  std::optional<bool> laser_on;  ///< last laser state sent (sequence mode)
  ParserStats parser;
  RepeatStats distance_repeats;   ///< distance frames: repeats, torn frames, fresh measurements
  std::uint64_t raw_repeats = 0;  ///< raw sets equal to the one before (not published)
  int last_stale_pixels = 0;
  RangeShares ranges;    ///< valid distance-frame pixels against the sensor's range (this period)
  std::string commands;  ///< CommandWatch::summary()
  bool ignores_laser_off = false;
  bus::Time last_scan_stamp;
  bus::Time last_receive;  ///< clock time of the last byte received
  bus::Time connected_at;  ///< clock time of the last successful open
  double last_saturated_share = 0.0;
  double last_valid_share = 0.0;
  double last_temperature_c = 0.0;
};

class LaserDriver : public bus::Node {
 public:
  explicit LaserDriver(bus::NodeOptions options);
  ~LaserDriver() override;

  void on_configure() override;
  void on_start() override;
  void on_stop() override;

  /// One I/O step, what the I/O thread loops on: (re)open the port when its
  /// backoff allows, send pending commands, read what arrives within
  /// `timeout`, parse, process and publish. Public for `threaded: false`
  /// (tests step it on a sim clock; embedding code calls it from its loop).
  void pump(std::chrono::milliseconds timeout);

  [[nodiscard]] DriverStatus status() const;
  [[nodiscard]] const DriverParams& params() const { return params_; }

 private:
  void declare_params();  // fills params_ from the node's parameters
  void run();
  void try_open(bus::Time now);
  void lost(const io::IoStatus& why);
  void send_pending();
  void take_set(const RawSet& set, std::uint64_t chunk_end, bus::Time t_recv);
  void take_distance(const DistanceFrame& f, std::uint64_t chunk_end, bus::Time t_recv);
  void publish_distance(const DistanceRepeats::Fresh& fresh);
  void publish_scan(const ProcessedScan& scan, std::uint32_t index, bus::Time stamp, float temperature_c);
  bus::Time stamp_of(std::uint64_t end_byte, std::uint64_t chunk_end, bus::Time t_recv, StreamMode kind) const;
  void on_command(const tinyline_msgs::msg::LaserCommand& cmd);
  void publish_diagnostics();
  void diagnose_level(const DriverStatus& s, const DriverStatus& prev, double dt,
                      diagnostic_msgs::msg::DiagnosticStatus& st) const;
  void diagnose_values(const DriverStatus& s, const DriverStatus& prev, double dt,
                       diagnostic_msgs::msg::DiagnosticStatus& st) const;

  DriverParams params_;
  std::optional<StreamMode> expected_;  // from `mode`; empty: either
  std::unique_ptr<io::PortOpener> opener_;
  std::unique_ptr<ScanProcessor> processor_;  // built in on_configure (loads the calibration)
  std::unique_ptr<ScanMessages> messages_;

  // I/O thread state (only the I/O thread touches these, or pump()'s caller).
  Parser parser_;
  std::unique_ptr<io::ByteStream> stream_;
  std::vector<std::uint8_t> buf_;
  ProcessedScan scan_;
  DistanceRepeats repeats_;
  std::optional<RawSet> last_set_;  // the last raw set published (repeat check)
  StalePixels stale_;
  CommandWatch watch_;
  bus::Time next_attempt_;
  double backoff_s_ = 0.0;
  std::optional<bus::Time> first_stamp_;
  std::optional<bus::Time> prev_stamp_;
  double scan_period_s_ = 0.0;

  // Shared with the executor thread (commands, diagnostics) and on_stop().
  mutable std::mutex mu_;
  std::condition_variable wake_;
  DriverStatus status_;
  std::optional<bool> laser_wanted_;
  bool laser_dirty_ = false;
  std::mutex stream_mu_;  // guards the stream pointer against interrupt() from on_stop / commands
  std::atomic<bool> stop_{false};
  std::thread io_thread_;

  // Diagnostics (executor thread).
  DriverStatus diag_prev_;
  bus::Time diag_prev_time_;
  bool diag_have_prev_ = false;

  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::RawScan>> raw_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::LineScan>> scan_pub_;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::LaserScan>> laser_scan_pub_;
  std::shared_ptr<bus::Publisher<sensor_msgs::msg::PointCloud2>> cloud_pub_;  // publish_cloud only
  std::shared_ptr<bus::Publisher<diagnostic_msgs::msg::DiagnosticArray>> diag_pub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LaserCommand>> command_sub_;
  std::shared_ptr<bus::Timer> diag_timer_;
};

/// Loads a calibration named as the `calibration` parameter does: a YAML
/// file, "public:NAME" (the public driver's sensors R J S K T), or "default"
/// (the shipped calibration of the simulated sensor). Throws
/// std::runtime_error saying what was wrong.
[[nodiscard]] CalibrationModel load_calibration(const std::string& spec);
/// The `calibration` parameter's file checks (a path unless default or public:NAME).
[[nodiscard]] bus::ParamConstraints calibration_file_constraints();
/// Where "default" points.
[[nodiscard]] std::string default_calibration_path();

}  // namespace tinyline::tiny_laser_driver
