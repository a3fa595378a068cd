// SPDX-License-Identifier: Apache-2.0
// The simulated sensor behind a pseudo-terminal that speaks the real serial
// framing (tiny_laser_driver/protocol.hpp), so a
// driver cannot tell it from the hardware. docs/simulator.md lists the bytes.
//
//   auto sys = SimulatedSystem::from_file("sim/config/scenes/calibration_rail.yaml");
//   VirtualDevice dev(sys, {.link_path = dir + "/ttyTINY0"});
//   dev.start();                       // the host opens dev.path() at 2 Mbaud
//   dev.unplug(); dev.replug();        // the path disappears and comes back
//   dev.stop();
//
// Two firmware profiles (the sensor's `firmware.profile`, or the options'
// override; firmware.hpp has what each computes):
//
// thesis_raw, the thesis's firmware, obeys the host:
//  * raw mode (default): continuous sets of read-outs at the sensor's
//    acquisition.raw_pulses (5 frames per set, the last flagged);
//  * distance mode: one distance frame per set at acquisition.distance_pulses,
//    0.1 mm per pixel from the on-board calibration;
//  * single-shot (the calibration firmware, Algorithm 1): 'R', n or the framed
//    reset enters it with n * 10 pulses; each 'S' / 'P' / framed sample sends
//    one raw frame (a set of one, flagged last); the framed stream-mode
//    command returns to continuous streaming;
//  * sequence mode (Algorithm 4): framed laser off (F8 02 10 00 8F) stops the
//    pulse timer (no light, no frames) and drops the partial set; laser on
//    (F8 02 10 01 8F) starts a new set at once.
//  Frames leave at the link rate (10 bits per byte at `baud`); a frame's
//  bytes are produced when its read-out completes. With no host on the port
//  the output is discarded (as an FTDI with no reader); when the host lags,
//  whole frames beyond the transmit buffer are dropped and counted.
//
// published, the public STM32 firmware: an accumulation cycle every
// firmware.cycle_s() (about 10 Hz) computes distances into the one frame
// buffer, which a circular DMA sends back to back at the link rate whether
// anyone listens or not (the same frame about 365 times a second at 2 Mbaud;
// a frame in flight when the buffer is rewritten goes out half old, half
// new). Nothing is sent before the first cycle ends. Host bytes are read and
// ignored.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <sim/firmware.hpp>
#include <sim/system.hpp>

namespace tinyline::sim {

/// Faults injected on the device-to-host bytes, for tests.
struct LinkFaults {
  double byte_error_rate = 0.0;  ///< probability per byte that one random bit flips
  double byte_drop_rate = 0.0;   ///< probability per byte that it is lost
  std::uint64_t seed = 1;
};

/// The thesis firmware's streaming mode (the published firmware is always kDistance).
enum class FirmwareMode { kRaw, kDistance, kSingleShot };

/// What the firmware put on the wire, before the link's faults: ground truth
/// for conformance checks (`tinyline sim serve --truth`).
struct WireTruth {
  enum class Kind { kRawFrame, kDistanceFrame, kPublishedCycle };
  Kind kind = Kind::kRawFrame;
  std::uint64_t sequence = 0;  ///< frames (thesis) or cycles (published) made so far
  double t_s = 0.0;            ///< shared time it was made
  bool queued = true;          ///< thesis: false when dropped before the link (no host, buffer full)
  const tiny_laser_driver::RawFrame* raw = nullptr;            ///< kRawFrame
  const tiny_laser_driver::DistanceFrame* distance = nullptr;  ///< kDistanceFrame
  const PublishedCycle* cycle = nullptr;                       ///< kPublishedCycle: read-outs, ambient, words
  const PublishedFirmware* firmware = nullptr;                 ///< kPublishedCycle: its constants and polynomial
};

struct VirtualDeviceOptions {
  std::string sensor;  ///< sensor name in the scene; empty: the first sensor
  /// A stable path for the host: a symlink to the current pty, created by
  /// start(), removed by unplug()/stop(), re-created by replug(). Anything
  /// already at the path is refused (start() throws), and only the device's
  /// own link is ever removed. Empty: none (path() is then the pty itself,
  /// which changes on replug).
  std::string link_path;
  double baud = 2000000.0;  ///< the FT232's rate; frames are paced at baud / 10 bytes per second
  /// The firmware; empty: the sensor's `firmware.profile`.
  std::optional<FirmwareProfile> firmware;
  FirmwareMode mode = FirmwareMode::kRaw;  ///< thesis firmware: the power-on mode
  bool laser_on = true;                    ///< false: silent until the host's laser-on (sequence mode)
  int single_shot_pulses = 100;            ///< pulses before the host's first reset command
  LinkFaults faults;
  std::size_t tx_buffer_bytes = 16384;  ///< device-side buffer; beyond it frames are dropped
};

struct VirtualDeviceStats {
  std::uint64_t sets = 0;               ///< sets measured
  std::uint64_t frames_sent = 0;        ///< frames whose bytes went to the pty (before faults)
  std::uint64_t frames_overflowed = 0;  ///< frames dropped because the host lagged
  std::uint64_t frames_no_host = 0;     ///< frames discarded while no host had the port open
  std::uint64_t bytes_no_host = 0;      ///< published firmware: bytes the DMA sent while no host had the port open
  std::uint64_t bytes_sent = 0;
  std::uint64_t bytes_corrupted = 0;   ///< bytes sent with a flipped bit
  std::uint64_t bytes_dropped = 0;     ///< bytes the fault injector removed
  std::uint64_t bytes_overrun = 0;     ///< bytes lost because the host did not read (beyond 64 KB waiting)
  std::uint64_t bytes_received = 0;    ///< host bytes read
  std::uint64_t commands = 0;          ///< host commands understood
  std::uint64_t commands_ignored = 0;  ///< of those, not acted on (the published firmware ignores them all)
  std::uint64_t command_garbage = 0;   ///< host bytes that were no command
  std::uint64_t cycles = 0;            ///< published firmware: accumulation cycles (buffer updates)
  std::uint64_t host_opens = 0;        ///< times a host opened the port
  std::uint64_t replugs = 0;
};

class VirtualDevice {
 public:
  /// Throws std::invalid_argument when the sensor is not in the scene.
  explicit VirtualDevice(std::shared_ptr<SimulatedSystem> system, VirtualDeviceOptions options = {});
  /// A device from a port string "sim:SCENE.yaml" or "sim:SCENE.yaml#sensor"
  /// (the driver's `port` parameter). Throws ConfigError / std::invalid_argument.
  static std::unique_ptr<VirtualDevice> from_port(const std::string& port, VirtualDeviceOptions options = {});
  /// The scene file and sensor name ("" for the first) of such a port string;
  /// throws std::invalid_argument when it is not one.
  static std::pair<std::string, std::string> parse_port(const std::string& port);
  ~VirtualDevice();
  VirtualDevice(const VirtualDevice&) = delete;
  VirtualDevice& operator=(const VirtualDevice&) = delete;

  /// Opens the pty (and the link) and starts the firmware thread. Throws
  /// std::system_error when the pty or the link cannot be made.
  void start();
  void stop();
  [[nodiscard]] bool running() const { return running_.load(); }

  /// Where the host opens the device: the link if configured, else the pty.
  [[nodiscard]] std::string path() const;
  /// The pty itself (changes on replug); empty while unplugged.
  [[nodiscard]] std::string pty_path() const;

  /// USB unplug: the pty closes (the host reads EOF / EIO) and the link
  /// disappears; the sensor is unpowered. replug() powers it up again on a
  /// fresh pty behind the same link, in its initial mode.
  void unplug();
  void replug();
  [[nodiscard]] bool plugged() const;
  /// The link stops for `seconds` (a USB hiccup): output waits; frames beyond
  /// the transmit buffer are dropped meanwhile.
  void stall(double seconds);
  void set_faults(const LinkFaults& faults);

  [[nodiscard]] VirtualDeviceStats stats() const;
  [[nodiscard]] FirmwareMode mode() const;
  [[nodiscard]] FirmwareProfile firmware() const { return profile_; }
  [[nodiscard]] bool laser_on() const;
  [[nodiscard]] std::size_t sensor_index() const { return sensor_; }
  [[nodiscard]] const std::shared_ptr<SimulatedSystem>& system() const { return system_; }
  /// Called from the device thread with every set it measures (ground truth
  /// for tests and for the scene node); keep it short.
  void on_set(std::function<void(const SensorSet&)> callback);
  /// Called from the device thread with every frame (thesis) or buffer
  /// update (published) the firmware makes; keep it short.
  void on_wire(std::function<void(const WireTruth&)> callback);

 private:
  struct State;
  // The firmware thread's loop and its steps (each called with mu_ held).
  void run();
  void power_on(double now);
  void poll_host();
  void apply_commands(double now);
  void apply_command(const tiny_laser_driver::HostCommand& c, double now);
  void run_firmware(double now, double& sleep_s);
  void run_published(double now);
  void run_dma_link(double now);
  void begin_set(double t0, const std::vector<int>& pulses);
  [[nodiscard]] const std::vector<int>& streaming_pulses() const;
  /// Queues the frames of the current set whose read-outs are done; true when the set is complete.
  bool emit_due_frames(double now, double& sleep_s);
  void emit_distance_frame(const SensorSet& set, double now);
  void enqueue(std::vector<std::uint8_t> bytes);
  void tell_wire(WireTruth truth, double now);
  void run_link(double now);
  std::vector<std::uint8_t> apply_faults(const std::vector<std::uint8_t>& out);
  void write_to_host(const std::vector<std::uint8_t>& wire);
  void flush_to_host();
  void open_pty();
  void close_pty();

  std::shared_ptr<SimulatedSystem> system_;
  VirtualDeviceOptions options_;
  std::size_t sensor_ = 0;
  FirmwareProfile profile_ = FirmwareProfile::kThesisRaw;
  std::unique_ptr<State> state_;
  mutable std::mutex mu_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_{false};
};

}  // namespace tinyline::sim
