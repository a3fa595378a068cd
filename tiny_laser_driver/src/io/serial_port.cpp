// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/io/serial_port.hpp>

#include <fcntl.h>
#include <grp.h>
#include <linux/serial.h>
#include <poll.h>
#include <pwd.h>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "termios2.hpp"

namespace fs = std::filesystem;

namespace tinyline::tiny_laser_driver::io {

namespace {

constexpr double kFtdiClock = 3'000'000.0;  // FT232R / FT232H baud generator base (48 MHz / 16)

std::string errno_text(int err) { return std::strerror(err); }

std::string owner_text(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "";
  std::string user = std::to_string(st.st_uid), grp = std::to_string(st.st_gid);
  if (const passwd* pw = ::getpwuid(st.st_uid)) user = pw->pw_name;
  if (const struct group* gr = ::getgrgid(st.st_gid)) grp = gr->gr_name;
  return fmt::format("owned by {}:{}, mode {:04o}", user, grp, st.st_mode & 07777);
}

std::string group_of(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "dialout";
  if (const struct group* gr = ::getgrgid(st.st_gid)) return gr->gr_name;
  return "dialout";
}

std::optional<speed_t> standard_speed(double baud) {
  static constexpr std::array<std::pair<unsigned, speed_t>, 31> kTable{{
      {50, B50},
      {75, B75},
      {110, B110},
      {134, B134},
      {150, B150},
      {200, B200},
      {300, B300},
      {600, B600},
      {1200, B1200},
      {1800, B1800},
      {2400, B2400},
      {4800, B4800},
      {9600, B9600},
      {19200, B19200},
      {38400, B38400},
      {57600, B57600},
      {115200, B115200},
      {230400, B230400},
      {460800, B460800},
      {500000, B500000},
      {576000, B576000},
      {921600, B921600},
      {1000000, B1000000},
      {1152000, B1152000},
      {1500000, B1500000},
      {2000000, B2000000},
      {2500000, B2500000},
      {3000000, B3000000},
      {3500000, B3500000},
      {4000000, B4000000},
      {0, B0},
  }};
  if (baud != std::floor(baud)) return std::nullopt;
  for (const auto& [rate, code] : kTable) {
    if (rate != 0 && rate == static_cast<unsigned>(baud)) return code;
  }
  return std::nullopt;
}

bool is_pty_path(const std::string& path) {
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  if (ec) return false;
  const std::string s = real.string();
  return s.rfind("/dev/pts/", 0) == 0 || s == "/dev/ptmx";
}

}  // namespace

FtdiRate ftdi_rate(double requested) {
  if (!(requested > 0.0)) return {0.0, 1.0};
  auto consider = [&](double divisor, FtdiRate& best) {
    const double actual = kFtdiClock / divisor;
    const double err = std::abs(actual - requested) / requested;
    if (err < best.relative_error) best = {actual, err};
  };
  FtdiRate best{0.0, 1e300};
  consider(1.0, best);  // divisor 0 in the chip's encoding: 3 Mbaud
  consider(1.5, best);  // divisor 1: 2 Mbaud
  // Divisors 2 .. 16383.875 in steps of 1/8.
  const double d = std::clamp(kFtdiClock / requested, 2.0, 16383.875);
  const double lo = std::floor(d * 8.0) / 8.0;
  consider(std::max(2.0, lo), best);
  consider(std::min(16383.875, lo + 0.125), best);
  return best;
}

std::string tty_driver(const std::string& tty_path, const std::string& sysfs_root) {
  const std::string name = fs::path(tty_path).filename().string();
  std::error_code ec;
  const fs::path link = fs::path(sysfs_root) / "sys/class/tty" / name / "device/driver";
  const fs::path target = fs::read_symlink(link, ec);
  if (ec) return "";
  return target.filename().string();
}

IoStatus open_error_status(int err, const std::string& path) {
  switch (err) {
    case ENOENT:
    case ENODEV:
    case ENXIO:
      return IoStatus::fail(IoError::kNotFound,
                            fmt::format("{}: no such device. Is the sensor plugged in? `tinyline sensors` lists the "
                                        "sensors attached; port usb:SERIAL finds a sensor wherever it is plugged",
                                        path));
    case EACCES:
    case EPERM: {
      const std::string owner = owner_text(path);
      return IoStatus::fail(
          IoError::kPermission,
          fmt::format("{}: permission denied{}. Add your user to the '{}' group (`sudo usermod -aG {} $USER`, then "
                      "log in again), or install the udev rule shipped with the driver "
                      "(tiny_laser_driver/config/99-tinyline-laser.rules: `sudo cp` it to /etc/udev/rules.d/, then "
                      "`sudo udevadm control --reload && sudo udevadm trigger`)",
                      path, owner.empty() ? "" : " (" + owner + ")", group_of(path), group_of(path)));
    }
    case EBUSY:
    case EWOULDBLOCK:
      return IoStatus::fail(IoError::kBusy,
                            fmt::format("{}: busy: another program holds the port (`fuser -v {}` names it; "
                                        "ModemManager probes new serial ports, the udev rule tells it to keep off). "
                                        "A sensor serves one driver at a time",
                                        path, path));
    case ENOTTY: return IoStatus::fail(IoError::kNotSerial, fmt::format("{}: not a serial port", path));
    case EIO: return IoStatus::fail(IoError::kDisconnected, fmt::format("{}: I/O error (the device went away)", path));
    default: return IoStatus::fail(IoError::kIo, fmt::format("{}: cannot open: {}", path, errno_text(err)));
  }
}

SerialPort::Opened SerialPort::open(const std::string& path, const SerialOptions& options) {
  if (!(options.baud > 0.0) || options.baud > 12'000'000.0) {
    return {nullptr, IoStatus::fail(IoError::kBadSetting, fmt::format("{}: baud rate {} out of range (1 to 12,000,000)",
                                                                      path, options.baud))};
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return {nullptr, open_error_status(errno, path)};
  auto fail = [&](IoStatus s) {
    ::close(fd);
    return Opened{nullptr, std::move(s)};
  };
  if (!::isatty(fd)) return fail(open_error_status(ENOTTY, path));
  if (options.exclusive) {
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) return fail(open_error_status(EBUSY, path));
    ::ioctl(fd, TIOCEXCL);  // refuse later opens by others (root excepted)
  }

  termios t{};
  if (::tcgetattr(fd, &t) != 0) return fail(open_error_status(errno, path));
  ::cfmakeraw(&t);
  t.c_cflag |= CLOCAL | CREAD;
  t.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | PARENB | CRTSCTS | CSIZE);
  t.c_cflag |= CS8;
  t.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  t.c_cc[VMIN] = 0;
  t.c_cc[VTIME] = 0;

  const bool pty = is_pty_path(path);
  double actual = options.baud;
  if (tty_driver(path, options.sysfs_root) == "ftdi_sio") {
    const FtdiRate r = ftdi_rate(options.baud);
    if (r.relative_error > options.max_baud_error) {
      return fail(IoStatus::fail(
          IoError::kBadSetting,
          fmt::format(
              "{}: an FTDI adapter cannot run at {:.0f} baud: the nearest rate it makes is {:.0f} ({:.1f}% off, "
              "more than the {:.1f}% allowed)",
              path, options.baud, r.actual_baud, 100.0 * r.relative_error, 100.0 * options.max_baud_error)));
    }
    actual = r.actual_baud;
  }
  const auto code = standard_speed(options.baud);
  if (code) {
    ::cfsetispeed(&t, *code);
    ::cfsetospeed(&t, *code);
  }
  if (::tcsetattr(fd, TCSANOW, &t) != 0) {
    const int err = errno;
    return fail(IoStatus::fail(IoError::kBadSetting, fmt::format("{}: cannot set raw 8N1 at {:.0f} baud: {}", path,
                                                                 options.baud, errno_text(err))));
  }
  if (!code) {
    if (const int err = detail::set_custom_baud(fd, static_cast<unsigned>(std::lround(options.baud))); err != 0) {
      return fail(IoStatus::fail(IoError::kBadSetting,
                                 fmt::format("{}: the serial driver refuses {:.0f} baud (termios2 BOTHER): {}", path,
                                             options.baud, errno_text(err))));
    }
  }
  if (options.low_latency && !pty) {
    // FTDI adapters hold bytes up to their latency timer (16 ms by default);
    // low latency makes it 1 ms, which keeps receive times close to arrival.
    serial_struct ss{};
    if (::ioctl(fd, TIOCGSERIAL, &ss) == 0) {
      ss.flags |= ASYNC_LOW_LATENCY;
      (void)::ioctl(fd, TIOCSSERIAL, &ss);
    }
  }
  ::tcflush(fd, TCIOFLUSH);  // stale bytes from before we opened carry no usable time

  const int wake = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake < 0) return fail(IoStatus::fail(IoError::kIo, fmt::format("{}: eventfd: {}", path, errno_text(errno))));
  return {std::unique_ptr<SerialPort>(new SerialPort(fd, wake, path, actual, pty)), {}};
}

SerialPort::SerialPort(int fd, int wake_fd, std::string path, double baud, bool pty)
    : fd_(fd), wake_fd_(wake_fd), path_(std::move(path)), baud_(baud), pty_(pty) {}

SerialPort::~SerialPort() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the flock
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

ReadResult SerialPort::read(std::span<std::uint8_t> buf, std::chrono::milliseconds timeout) {
  pollfd p[2] = {{fd_, POLLIN, 0}, {wake_fd_, POLLIN, 0}};
  const int ms = static_cast<int>(std::clamp<std::int64_t>(timeout.count(), 0, std::numeric_limits<int>::max()));
  const int r = ::poll(p, 2, ms);
  if (r < 0) {
    if (errno == EINTR) return {};
    return {0, IoStatus::fail(IoError::kIo, fmt::format("{}: poll: {}", path_, errno_text(errno)))};
  }
  if (p[1].revents & POLLIN) {
    std::uint64_t v = 0;
    (void)!::read(wake_fd_, &v, sizeof v);
    return {};
  }
  if (p[0].revents & POLLIN) {
    const ssize_t n = ::read(fd_, buf.data(), buf.size());
    if (n > 0) return {static_cast<std::size_t>(n), {}};
    if (n == 0) {
      return {0, IoStatus::fail(IoError::kDisconnected, fmt::format("{}: hang-up (device unplugged?)", path_))};
    }
    if (errno == EAGAIN || errno == EINTR) return {};
    if (errno == EIO || errno == ENODEV || errno == ENXIO) {
      return {0, IoStatus::fail(IoError::kDisconnected,
                                fmt::format("{}: {} (device unplugged?)", path_, errno_text(errno)))};
    }
    return {0, IoStatus::fail(IoError::kIo, fmt::format("{}: read: {}", path_, errno_text(errno)))};
  }
  if (p[0].revents & (POLLHUP | POLLERR | POLLNVAL)) {
    return {0, IoStatus::fail(IoError::kDisconnected, fmt::format("{}: hang-up (device unplugged?)", path_))};
  }
  return {};
}

IoStatus SerialPort::write(std::span<const std::uint8_t> bytes) {
  std::size_t done = 0;
  int waits = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EINTR) && waits < 10) {
      pollfd p{fd_, POLLOUT, 0};
      (void)::poll(&p, 1, 10);
      ++waits;
      continue;
    }
    if (n < 0 && (errno == EIO || errno == ENODEV || errno == ENXIO)) {
      return IoStatus::fail(IoError::kDisconnected, fmt::format("{}: write: {}", path_, errno_text(errno)));
    }
    return IoStatus::fail(IoError::kIo, fmt::format("{}: write: {}", path_, n < 0 ? errno_text(errno) : "no progress"));
  }
  return {};
}

void SerialPort::interrupt() {
  const std::uint64_t one = 1;
  (void)!::write(wake_fd_, &one, sizeof one);
}

std::string SerialPort::describe() const {
  return fmt::format("{} at {:.0f} baud{}", path_, baud_, pty_ ? " (pseudo-terminal)" : "");
}

}  // namespace tinyline::tiny_laser_driver::io
