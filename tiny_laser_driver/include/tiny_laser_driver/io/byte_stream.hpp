// SPDX-License-Identifier: Apache-2.0
// The driver reads a byte stream: the serial port, the simulator's pty and an
// in-memory link all implement this small interface, so most driver logic is
// tested without a device.
//
// Not a core header: this is I/O (target tinyline::tiny_laser_driver_io).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/common/status.hpp>

namespace tinyline::tiny_laser_driver::io {

/// What went wrong on a port. The kind decides the driver's reaction
/// (kNotFound / kDisconnected: retry with backoff; kPermission / kBusy /
/// kBadSetting: retry too, but the message tells the user what to fix).
enum class IoError {
  kNone,
  kNotFound,      ///< no such device (not plugged in, wrong path or serial number)
  kPermission,    ///< the device exists but this user may not open it
  kBusy,          ///< another process holds the port
  kNotSerial,     ///< the path is not a serial port
  kBadSetting,    ///< a baud rate (or other setting) the port cannot do
  kDisconnected,  ///< the device went away while open (unplug, hang-up)
  kIo,            ///< any other I/O failure (read or write)
};
std::string_view to_string(IoError e);

/// The common code for an IoError: NotFound (kNotFound), InvalidArgument
/// (kBadSetting, kNotSerial), OpenFailed (kPermission, kBusy), ReadFailed
/// (kDisconnected, kIo).
[[nodiscard]] common::StatusCode status_code(IoError e);

/// A port's outcome: a common::Status (code, message: what, where, and what
/// to do about it) with the IoError the driver's reaction depends on.
struct IoStatus : common::Status {
  IoError error = IoError::kNone;
  static IoStatus fail(IoError e, std::string message) {
    IoStatus s;
    s.code = status_code(e);
    s.message = std::move(message);
    s.error = e;
    return s;
  }
};

struct ReadResult {
  std::size_t bytes = 0;  ///< bytes read (0 on a timeout or an error)
  IoStatus status;        ///< not ok: the stream is unusable (reopen it)
};

class ByteStream {
 public:
  virtual ~ByteStream() = default;
  /// Reads what is available (at most buf.size() bytes), waiting up to
  /// `timeout` for the first byte. 0 bytes with an ok status is a timeout.
  [[nodiscard]] virtual ReadResult read(std::span<std::uint8_t> buf, std::chrono::milliseconds timeout) = 0;
  /// Writes all of `bytes` (host commands are a few bytes).
  [[nodiscard]] virtual IoStatus write(std::span<const std::uint8_t> bytes) = 0;
  /// Makes a read() blocked in another thread return at once (thread-safe).
  virtual void interrupt() = 0;
  /// The link's bit rate [baud] (what the timestamps use), 0 if unknown.
  [[nodiscard]] virtual double baud() const = 0;
  /// "/dev/ttyUSB0 at 2000000 baud", for logs and diagnostics.
  [[nodiscard]] virtual std::string describe() const = 0;
};

/// A stream just opened, or why it could not be.
struct OpenResult {
  std::unique_ptr<ByteStream> stream;
  IoStatus status;
};

/// An in-memory device link for tests and embedding: the "device" side
/// pushes bytes and can unplug and replug; open() gives the host side. Reads
/// never wait when `timeout` is 0, so a test can step a driver without sleeping.
class MemoryLink : public std::enable_shared_from_this<MemoryLink> {
 public:
  static std::shared_ptr<MemoryLink> create(std::string name = "mem", double baud = 2'000'000.0);

  /// The host side, or kNotFound while unplugged. Opening again while a host
  /// side is open fails with kBusy, as a real exclusive port does.
  OpenResult open();

  /// Device side: bytes for the host to read; lost (as on a real port) while
  /// unplugged or while no host side is open.
  void push(std::span<const std::uint8_t> bytes);
  /// Device side: what the host wrote (host commands), and forget it.
  std::vector<std::uint8_t> take_written();
  /// The device goes away: the open host side reads kDisconnected (after
  /// the bytes already queued, if `keep_queued`), open() fails until replug().
  void unplug(bool keep_queued = false);
  void replug();
  [[nodiscard]] bool plugged() const;
  /// Bytes pushed and not yet read by the host.
  [[nodiscard]] std::size_t queued() const;
  /// Device side: waits until a host side is open (true) or the timeout passes.
  bool wait_for_host(std::chrono::milliseconds timeout);
  /// Times open() succeeded.
  [[nodiscard]] int opens() const;

  const std::string& name() const { return name_; }
  double baud() const { return baud_; }

  // Host side (used by the stream open() returns).
  struct State;
  MemoryLink(std::string name, double baud);

 private:
  std::string name_;
  double baud_;
  std::shared_ptr<State> state_;
};

}  // namespace tinyline::tiny_laser_driver::io
