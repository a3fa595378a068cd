// SPDX-License-Identifier: Apache-2.0
// `tinyline sim serve`: one simulated sensor of a scene on a pseudo-terminal
// that any serial program can open (a user's own driver, a terminal, the
// public ROS 1 driver), with a live line of what it sent and received,
// unplug/replug on a key or SIGUSR1, and a clean stop on Ctrl-C or SIGTERM.
#if __has_include(<sim/virtual_device.hpp>)

#include <poll.h>
#include <signal.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <sim/virtual_device.hpp>
#include <tinyline/common/files.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"

namespace {

namespace cli = tinyline::cli;
namespace sim = tinyline::sim;
namespace tld = tinyline::tiny_laser_driver;
using Clock = std::chrono::steady_clock;

volatile std::sig_atomic_t g_stop = 0;
volatile std::sig_atomic_t g_toggle = 0;

extern "C" void on_stop_signal(int) { g_stop = 1; }
extern "C" void on_toggle_signal(int) { g_toggle = 1; }

struct ServeOptions {
  std::string scene;
  std::string sensor;
  std::string link;
  std::string firmware;
  std::string truth;
  double baud = 2'000'000.0;
  double duration_s = 0.0;
};

// The ground truth of every frame (or buffer update), one JSON object per
// line, written through an AtomicFile (refusing a link, a device, a FIFO and
// the scene it reads) and renamed into place when the server stops.
class TruthFile {
 public:
  TruthFile(const std::string& path, const std::string& scene)
      : file_(path, {.inputs = {scene}, .what = "truth file"}) {}
  void write(const sim::WireTruth& w) {
    std::lock_guard lock(mu_);
    buffer_ += line(w);
    buffer_ += '\n';
    if (buffer_.size() >= kFlushBytes) flush();
  }
  /// Writes the rest and renames the file into place; throws FileError (also
  /// for a write that failed on the device's thread, e.g. a full disk).
  void close() {
    std::lock_guard lock(mu_);
    flush();
    if (!error_.empty()) throw tinyline::files::FileError(error_);
    file_.commit();
  }

 private:
  static constexpr std::size_t kFlushBytes = 1 << 16;
  // Called on the device's thread: an error is kept for close(), not thrown there.
  void flush() {
    if (!error_.empty()) return;
    try {
      file_.write(buffer_);
    } catch (const tinyline::files::FileError& e) {
      error_ = e.what();
    }
    buffer_.clear();
  }
  static std::string line(const sim::WireTruth& w) {
    const std::string head = fmt::format(R"({{"seq": {}, "t": {}, "queued": {})", w.sequence, w.t_s, w.queued);
    if (w.kind == sim::WireTruth::Kind::kRawFrame) {
      const tld::RawFrame& f = *w.raw;
      return fmt::format(R"({}, "kind": "raw", "index_word": {}, "packed": {}, "a": [{}], "b": [{}]}})", head,
                         tld::last_frame_word(f.index, f.last), f.temperature_decic * 100 + f.pulses / 10,
                         fmt::join(f.a, ","), fmt::join(f.b, ","));
    }
    if (w.kind == sim::WireTruth::Kind::kDistanceFrame) {
      return fmt::format(R"({}, "kind": "distance", "distance": [{}]}})", head, fmt::join(w.distance->distance, ","));
    }
    const sim::PublishedCycle& c = *w.cycle;
    std::string readouts;
    for (const auto& r : c.readouts) {
      readouts += fmt::format(R"({}{{"pulses": {}, "a": [{}], "b": [{}]}})", readouts.empty() ? "" : ", ", r.pulses,
                              fmt::join(r.a, ","), fmt::join(r.b, ","));
    }
    const sim::FirmwareParams& fw = w.firmware->params();
    std::string copies;
    for (const auto& [dst, src] : sim::kPublishedPixelCopies)
      copies += fmt::format("{}[{}, {}]", copies.empty() ? "" : ", ", dst, src);
    return fmt::format(
        R"({}, "kind": "published", "distance": [{}], "ambient": {}, "readouts": [{}], "firmware": {{"sensitivity_ratio": {}, "compensated_pixel": {}, "compensated_pixel_factor": {}, "saturation_counts": {}, "poly": [{}], "copies": [{}]}}}})",
        head, fmt::join(c.distance, ","), c.ambient_counts_per_pulse, readouts, fw.sensitivity_ratio,
        fw.compensated_pixel, fw.compensated_pixel_factor, w.firmware->saturation_counts(),
        fmt::join(w.firmware->polynomial(), ","), copies);
  }
  tinyline::files::AtomicFile file_;
  std::mutex mu_;
  std::string buffer_;
  std::string error_;
};

// Single keys from a terminal on stdin (no echo, no line buffering) while serving.
class KeyReader {
 public:
  KeyReader() {
    tty_ = ::isatty(STDIN_FILENO) && tcgetattr(STDIN_FILENO, &saved_) == 0;
    if (!tty_) return;
    termios t = saved_;
    t.c_lflag &= static_cast<tcflag_t>(~(ICANON | ECHO));
    tcsetattr(STDIN_FILENO, TCSANOW, &t);
  }
  ~KeyReader() {
    if (tty_) tcsetattr(STDIN_FILENO, TCSANOW, &saved_);
  }
  /// Waits up to `ms` for a key; 0 when none.
  char wait(int ms) const {
    pollfd p{STDIN_FILENO, POLLIN, 0};
    if (!tty_) {
      ::poll(nullptr, 0, ms);  // interrupted early by a signal
      return 0;
    }
    if (::poll(&p, 1, ms) <= 0) return 0;
    char c = 0;
    return ::read(STDIN_FILENO, &c, 1) == 1 ? c : 0;
  }
  [[nodiscard]] bool tty() const { return tty_; }

 private:
  bool tty_ = false;
  termios saved_{};
};

std::string status_line(const sim::VirtualDevice& dev, double elapsed_s) {
  const auto s = dev.stats();
  return fmt::format(
      "{:.1f} s  {}  sent {} frames ({} bytes, {} lost to a slow host)  received {} bytes: {} commands ({} ignored), "
      "{} garbage",
      elapsed_s, dev.plugged() ? "plugged" : "UNPLUGGED", s.frames_sent, s.bytes_sent, s.bytes_overrun,
      s.bytes_received, s.commands, s.commands_ignored, s.command_garbage);
}

void announce(const sim::VirtualDevice& dev, const ServeOptions& o) {
  const std::string pty = dev.pty_path();
  if (o.link.empty()) {
    fmt::print("serving on {}\n", pty);
  } else {
    fmt::print("serving on {} -> {}\n", o.link, pty);
  }
  std::fflush(stdout);
}

sim::VirtualDeviceOptions device_options(const ServeOptions& o) {
  sim::VirtualDeviceOptions d;
  d.sensor = o.sensor;
  d.link_path = o.link;
  d.baud = o.baud;
  if (!o.firmware.empty()) d.firmware = sim::firmware_profile_from_string(o.firmware);
  return d;
}

void toggle_plug(sim::VirtualDevice& dev, const ServeOptions& o) {
  if (dev.plugged()) {
    dev.unplug();
    fmt::print("\nunplugged\n");
  } else {
    dev.replug();
    fmt::print("\nreplugged\n");
    announce(dev, o);
  }
  std::fflush(stdout);
}

int serve(const ServeOptions& o) {
  auto system = sim::SimulatedSystem::from_file(o.scene);  // ConfigError names file, line and field
  sim::VirtualDevice dev(system, device_options(o));
  std::unique_ptr<TruthFile> truth;
  if (!o.truth.empty()) {
    truth = std::make_unique<TruthFile>(o.truth, o.scene);
    dev.on_wire([t = truth.get()](const sim::WireTruth& w) { t->write(w); });
  }
  fmt::print("tinyline sim serve: sensor '{}' of scene '{}', firmware {}, {} baud 8N1\n",
             system->sensor_name(dev.sensor_index()), system->scene_name(), sim::to_string(dev.firmware()), o.baud);
  dev.start();
  announce(dev, o);
  const KeyReader keys;
  fmt::print("{}Ctrl-C or SIGTERM stops; SIGUSR1 unplugs and replugs\n",
             keys.tty() ? "u unplugs and replugs, q or " : "");
  std::fflush(stdout);
  const auto t0 = Clock::now();
  auto last_status = t0;
  while (!g_stop) {
    const char key = keys.wait(100);
    if (key == 'q') break;
    if (key == 'u' || g_toggle) {
      g_toggle = 0;
      toggle_plug(dev, o);
    }
    const auto now = Clock::now();
    const double elapsed = std::chrono::duration<double>(now - t0).count();
    if (o.duration_s > 0 && elapsed >= o.duration_s) break;
    if (now - last_status >= std::chrono::milliseconds(keys.tty() ? 200 : 1000)) {
      last_status = now;
      const std::string line = status_line(dev, elapsed);
      if (keys.tty()) {
        fmt::print("\r{}\033[K", line);  // one line, redrawn
      } else {
        fmt::print("{}\n", line);
      }
      std::fflush(stdout);
    }
  }
  const std::string last = status_line(dev, std::chrono::duration<double>(Clock::now() - t0).count());
  dev.stop();
  if (truth) truth->close();
  fmt::print("\nstopped: {}\n", last);
  return 0;
}

int run_serve(const ServeOptions& o) {
  struct sigaction stop {};
  stop.sa_handler = on_stop_signal;
  sigaction(SIGINT, &stop, nullptr);
  sigaction(SIGTERM, &stop, nullptr);
  struct sigaction toggle {};
  toggle.sa_handler = on_toggle_signal;
  sigaction(SIGUSR1, &toggle, nullptr);
  return serve(o);
}

tinyline::tools::CommandRun setup_serve(cli::App& cmd) {
  auto o = std::make_shared<ServeOptions>();
  cmd.add_option("scene", o->scene, "scene YAML (sim/config/scenes/...)")->required()->check(cli::existing_file());
  cmd.add_option("--sensor", o->sensor, "sensor name in the scene (default: the first)");
  cmd.add_option("--link", o->link, "make PATH a symlink to the pty (kept across unplug/replug)");
  cmd.add_option("--firmware", o->firmware, "override the sensor's firmware profile")
      ->check(cli::one_of({"published", "thesis_raw"}));
  cmd.add_option("--truth", o->truth, "write what the firmware sent, one JSON object per line, to FILE");
  cmd.add_option("--baud", o->baud, "link rate [bit/s]")->check(cli::finite_above(1200.0, true, 12e6));
  cmd.add_option("--duration", o->duration_s, "stop after this many seconds (0: until stopped)")
      ->check(cli::non_negative());
  cmd.footer("docs/driver.md, \"tinyline sim serve\"");
  return [o] { return run_serve(*o); };
}

tinyline::tools::CommandRun setup_sim(cli::App& cmd) {
  return tinyline::tools::parsing::nested(
      cmd, {{"serve", "serve one sensor of a scene on a pty any serial program can open", &setup_serve}});
}

const tinyline::tools::CommandRegistration kSim{"sim", "the simulated sensor on a pty: tinyline sim serve SCENE.yaml",
                                                &setup_sim};

}  // namespace

#endif
