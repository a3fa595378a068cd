// SPDX-License-Identifier: Apache-2.0
// A termios serial port (Linux): raw 8N1, no flow control, any standard rate
// up to 4,000,000 baud and, through termios2/BOTHER, any other rate; on an
// FTDI adapter only the rates its divisor can make (3 MHz / n, n in steps of
// 1/8) are accepted, and the one actually used is what timestamps are computed
// with. Also works on a pseudo-terminal (the simulator's virtual device).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <tiny_laser_driver/io/byte_stream.hpp>

namespace tinyline::tiny_laser_driver::io {

struct SerialOptions {
  double baud = 2'000'000;  ///< [bit/s]; the sensor's FT232R runs at 2,000,000
  bool exclusive = true;    ///< lock the port (flock + TIOCEXCL): one driver per sensor
  bool low_latency = true;  ///< ask the kernel for low latency (FTDI latency timer 16 -> 1 ms)
  /// Largest relative error between the requested rate and the one an FTDI
  /// divisor makes (the FT232R data sheet allows 3% in total).
  double max_baud_error = 0.03;
  /// Where sys/ lives, to find the tty's kernel driver (tests: a fake tree).
  std::string sysfs_root = "/";
};

/// The rate an FT232R/FT232H (3 MHz base clock, 1/8 sub-divisor) makes for a
/// request: 3,000,000, 2,000,000, or 3,000,000 / (n + k/8) with n >= 2.
struct FtdiRate {
  double actual_baud = 0.0;
  double relative_error = 0.0;  ///< |actual - requested| / requested
};
[[nodiscard]] FtdiRate ftdi_rate(double requested_baud);

/// The kernel driver bound to a tty ("ftdi_sio", "cp210x", "" for a pty or
/// unknown), read from sysfs under `sysfs_root` (tests point it at a fake tree).
[[nodiscard]] std::string tty_driver(const std::string& tty_path, const std::string& sysfs_root = "/");

/// An open serial port. Reads wait with poll() and can be interrupted from
/// another thread; a hang-up or EIO (the USB adapter went away) reads as
/// kDisconnected.
class SerialPort : public ByteStream {
 public:
  struct Opened {
    std::unique_ptr<SerialPort> port;
    IoStatus status;  ///< why it failed: names the path and what to do
  };
  [[nodiscard]] static Opened open(const std::string& path, const SerialOptions& options = {});

  ~SerialPort() override;
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  [[nodiscard]] ReadResult read(std::span<std::uint8_t> buf, std::chrono::milliseconds timeout) override;
  [[nodiscard]] IoStatus write(std::span<const std::uint8_t> bytes) override;
  void interrupt() override;
  [[nodiscard]] double baud() const override { return baud_; }
  [[nodiscard]] std::string describe() const override;

  const std::string& path() const { return path_; }
  /// True when the port is a pseudo-terminal (the simulator): its baud rate is nominal.
  [[nodiscard]] bool is_pty() const { return pty_; }

 private:
  SerialPort(int fd, int wake_fd, std::string path, double baud, bool pty);
  int fd_ = -1;
  int wake_fd_ = -1;  // eventfd: interrupt() makes poll() return
  std::string path_;
  double baud_ = 0.0;
  bool pty_ = false;
};

/// The status an open() failing with `err` (errno) on `path` gets: which
/// failure it is and what to do (the dialout group or the udev rule for a
/// permission error, the process to look for when busy, ...).
[[nodiscard]] IoStatus open_error_status(int err, const std::string& path);

}  // namespace tinyline::tiny_laser_driver::io
