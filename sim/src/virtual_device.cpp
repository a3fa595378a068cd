// SPDX-License-Identifier: Apache-2.0
#include <sim/virtual_device.hpp>

#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <deque>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <utility>

#include <tiny_laser_driver/protocol.hpp>

#include <sim/firmware.hpp>

#include <tinyline/common/random.hpp>

namespace tinyline::sim {

namespace tld = tiny_laser_driver;

struct VirtualDevice::State {
  // Link.
  int master = -1;
  std::string pty_name;
  bool link_made = false;  // options.link_path is the symlink this device made to pty_name
  bool plugged = false;
  bool host_present = false;
  double stall_until = -1.0;
  LinkFaults faults;
  common::XoshiroRandom fault_rng{1};
  std::deque<std::vector<std::uint8_t>> tx;  // whole frames waiting to be sent
  std::size_t tx_bytes = 0;
  std::size_t tx_offset = 0;  // bytes of tx.front() already sent
  double last_write_t = 0.0;
  tld::CommandParser commands;

  // Firmware.
  FirmwareMode mode = FirmwareMode::kRaw;
  bool laser = true;
  int shot_pulses = 100;
  bool shot_requested = false;
  std::optional<SensorSet> set;       // the set being read out
  std::vector<tld::RawFrame> frames;  // its frames (raw and single shot)
  std::size_t next_frame = 0;
  std::uint64_t index = 0;
  std::optional<tld::CalibrationModel> onboard;  // distance mode, made on first use
  std::uint64_t frames_made = 0;
  std::uint64_t garbage_seen = 0;  // the command parser's garbage count already in stats

  // Published firmware: one frame buffer, sent round and round by the DMA.
  std::optional<PublishedFirmware> published;  // made in start()
  std::vector<std::uint8_t> txbuff;            // the frame buffer (header, 272 words, ender)
  bool dma_running = false;                    // from the end of the first cycle on
  std::size_t dma_pos = 0;                     // next byte of txbuff the DMA sends
  double cycle_start = 0.0;                    // shared time the current cycle began

  VirtualDeviceStats stats;
  std::function<void(const SensorSet&)> on_set;
  std::function<void(const WireTruth&)> on_wire;
  std::vector<std::uint8_t> to_host;  // bytes the pty could not take yet
};

namespace {
constexpr std::size_t kHostBufferBytes = 65536;  // what a host's serial driver holds for a slow reader
}  // namespace

VirtualDevice::VirtualDevice(std::shared_ptr<SimulatedSystem> system, VirtualDeviceOptions options)
    : system_(std::move(system)), options_(std::move(options)), state_(std::make_unique<State>()) {
  if (!system_) throw std::invalid_argument("virtual device: no simulated system");
  if (system_->sensor_count() == 0) throw std::invalid_argument("virtual device: the scene has no sensor");
  sensor_ = options_.sensor.empty() ? 0 : system_->sensor_index(options_.sensor);
  if (!(options_.baud > 0.0)) throw std::invalid_argument("virtual device: baud must be > 0");
  if (options_.single_shot_pulses < 10 || options_.single_shot_pulses > 990 || options_.single_shot_pulses % 10 != 0)
    throw std::invalid_argument("virtual device: single_shot_pulses must be a multiple of 10 in [10, 990]");
  state_->faults = options_.faults;
  state_->fault_rng = common::XoshiroRandom(options_.faults.seed);
  profile_ = options_.firmware.value_or(system_->sensor(sensor_).params().firmware.profile);
}

std::pair<std::string, std::string> VirtualDevice::parse_port(const std::string& port) {
  if (port.rfind("sim:", 0) != 0)
    throw std::invalid_argument("virtual device port must look like sim:SCENE.yaml[#sensor], got '" + port + "'");
  std::string scene = port.substr(4);
  std::string sensor;
  if (const auto hash = scene.find('#'); hash != std::string::npos) {
    sensor = scene.substr(hash + 1);
    scene = scene.substr(0, hash);
  }
  if (scene.empty()) throw std::invalid_argument("virtual device port '" + port + "' names no scene file");
  return {scene, sensor};
}

std::unique_ptr<VirtualDevice> VirtualDevice::from_port(const std::string& port, VirtualDeviceOptions options) {
  auto [scene, sensor] = parse_port(port);
  if (!sensor.empty()) options.sensor = std::move(sensor);
  return std::make_unique<VirtualDevice>(SimulatedSystem::shared(scene), std::move(options));
}

VirtualDevice::~VirtualDevice() { stop(); }

namespace {

// Makes `link` a symbolic link to the pty. symlink() never replaces: whatever
// is at `link` (a user's file, the scene, a device, another link) is refused.
void make_link(const std::string& link, const std::string& pty) {
  if (::symlink(pty.c_str(), link.c_str()) == 0) return;
  const int e = errno;
  if (e == EEXIST) {
    throw std::system_error(e, std::generic_category(),
                            "virtual device: link '" + link +
                                "' exists and is not this device's link: not replaced (remove it or give another "
                                "path)");
  }
  throw std::system_error(e, std::generic_category(), "virtual device: cannot create the link '" + link + "'");
}

// Removes `link` only while it is still the link made to `pty`: never what
// someone put there since.
void remove_own_link(const std::string& link, const std::string& pty) {
  char target[4096];
  const ssize_t n = ::readlink(link.c_str(), target, sizeof target);
  if (n > 0 && std::string(target, static_cast<std::size_t>(n)) == pty) ::unlink(link.c_str());
}

}  // namespace

void VirtualDevice::open_pty() {
  State& s = *state_;
  const int m = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
  if (m < 0) throw std::system_error(errno, std::generic_category(), "virtual device: posix_openpt");
  if (grantpt(m) != 0 || unlockpt(m) != 0) {
    const int e = errno;
    ::close(m);
    throw std::system_error(e, std::generic_category(), "virtual device: grantpt/unlockpt");
  }
  char name[128];
  if (ptsname_r(m, name, sizeof name) != 0) {
    const int e = errno;
    ::close(m);
    throw std::system_error(e, std::generic_category(), "virtual device: ptsname");
  }
  // Raw line discipline, and one open/close of the slave so that the master
  // reports a hang-up until a host opens it (bytes before that are discarded).
  const int sl = ::open(name, O_RDWR | O_NOCTTY);
  if (sl >= 0) {
    termios t{};
    if (tcgetattr(sl, &t) == 0) {
      cfmakeraw(&t);
      cfsetispeed(&t, B2000000);
      cfsetospeed(&t, B2000000);
      tcsetattr(sl, TCSANOW, &t);
    }
    ::close(sl);
  }
  s.master = m;
  s.pty_name = name;
  s.host_present = false;
  s.plugged = true;
  if (!options_.link_path.empty()) {
    try {
      make_link(options_.link_path, name);
    } catch (...) {
      ::close(std::exchange(s.master, -1));  // not plugged in: no port without its link
      s.plugged = false;
      throw;
    }
    s.link_made = true;
  }
}

void VirtualDevice::close_pty() {
  State& s = *state_;
  if (s.link_made) remove_own_link(options_.link_path, s.pty_name);
  s.link_made = false;
  if (s.master >= 0) ::close(s.master);
  s.master = -1;
  s.plugged = false;
  s.host_present = false;
  s.tx.clear();
  s.tx_bytes = 0;
  s.tx_offset = 0;
  s.to_host.clear();
}

void VirtualDevice::start() {
  if (running_.load()) return;
  {
    std::lock_guard lock(mu_);
    State& s = *state_;
    // The on-board calibrations take a moment: make them before streaming starts.
    const SensorParams& params = system_->sensor(sensor_).params();
    if (profile_ == FirmwareProfile::kPublished && !s.published) s.published.emplace(params);
    if (profile_ == FirmwareProfile::kThesisRaw && options_.mode == FirmwareMode::kDistance && !s.onboard) {
      s.onboard = factory_calibration(params);
    }
    open_pty();
    power_on(system_->now());
  }
  stop_ = false;
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

void VirtualDevice::stop() {
  if (!running_.load() && !thread_.joinable()) return;
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  running_ = false;
  std::lock_guard lock(mu_);
  system_->set_emitting(sensor_, false, system_->now());
  close_pty();
}

std::string VirtualDevice::path() const {
  std::lock_guard lock(mu_);
  return options_.link_path.empty() ? state_->pty_name : options_.link_path;
}

std::string VirtualDevice::pty_path() const {
  std::lock_guard lock(mu_);
  return state_->plugged ? state_->pty_name : std::string();
}

void VirtualDevice::unplug() {
  std::lock_guard lock(mu_);
  State& s = *state_;
  if (!s.plugged) return;
  close_pty();
  s.set.reset();
  s.frames.clear();
  system_->set_emitting(sensor_, false, system_->now());
}

void VirtualDevice::replug() {
  std::lock_guard lock(mu_);
  State& s = *state_;
  if (s.plugged) return;
  open_pty();
  power_on(system_->now());
  ++s.stats.replugs;
}

void VirtualDevice::power_on(double now) {
  // The firmware starts over in its initial mode.
  State& s = *state_;
  s.mode = profile_ == FirmwareProfile::kPublished ? FirmwareMode::kDistance : options_.mode;
  s.laser = profile_ == FirmwareProfile::kPublished || options_.laser_on;
  s.shot_pulses = options_.single_shot_pulses;
  s.shot_requested = false;
  s.commands = tld::CommandParser{};
  s.garbage_seen = 0;
  s.last_write_t = now;
  s.txbuff.assign(tld::kDistanceFrameBytes, 0);
  s.dma_running = false;
  s.dma_pos = 0;
  s.cycle_start = now;
}

bool VirtualDevice::plugged() const {
  std::lock_guard lock(mu_);
  return state_->plugged;
}

void VirtualDevice::stall(double seconds) {
  std::lock_guard lock(mu_);
  state_->stall_until = system_->now() + std::max(0.0, seconds);
}

void VirtualDevice::set_faults(const LinkFaults& faults) {
  std::lock_guard lock(mu_);
  state_->faults = faults;
  state_->fault_rng = common::XoshiroRandom(faults.seed);
}

VirtualDeviceStats VirtualDevice::stats() const {
  std::lock_guard lock(mu_);
  return state_->stats;
}

FirmwareMode VirtualDevice::mode() const {
  std::lock_guard lock(mu_);
  return state_->mode;
}

bool VirtualDevice::laser_on() const {
  std::lock_guard lock(mu_);
  return state_->laser;
}

void VirtualDevice::on_set(std::function<void(const SensorSet&)> callback) {
  std::lock_guard lock(mu_);
  state_->on_set = std::move(callback);
}

void VirtualDevice::on_wire(std::function<void(const WireTruth&)> callback) {
  std::lock_guard lock(mu_);
  state_->on_wire = std::move(callback);
}

void VirtualDevice::run() {
  while (!stop_.load()) {
    double sleep_s = 0.001;
    {
      std::lock_guard lock(mu_);
      State& s = *state_;
      const double now = system_->now();
      if (!s.plugged) {
        s.set.reset();  // unpowered: nothing happens until replug()
      } else {
        poll_host();
        apply_commands(now);
        if (profile_ == FirmwareProfile::kPublished) {
          run_published(now);
          run_dma_link(now);
          if (s.dma_running) sleep_s = std::min(sleep_s, 0.0005);
        } else {
          run_firmware(now, sleep_s);
          run_link(now);
        }
        if (s.host_present && !s.to_host.empty()) flush_to_host();
        if (!s.tx.empty() || !s.to_host.empty()) sleep_s = std::min(sleep_s, 0.0005);
      }
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(std::max(1e-4, sleep_s)));
  }
}

void VirtualDevice::poll_host() {
  State& s = *state_;
  // Host presence: a hang-up on the master means nobody has the port open.
  pollfd p{s.master, POLLIN, 0};
  ::poll(&p, 1, 0);
  const bool present = !(p.revents & POLLHUP);
  if (present && !s.host_present) ++s.stats.host_opens;
  if (!present && s.host_present) {
    // The host closed the port: what it did not read is gone.
    s.stats.frames_no_host += s.tx.size();
    s.tx.clear();
    s.tx_bytes = 0;
    s.tx_offset = 0;
    s.to_host.clear();
    tcflush(s.master, TCIOFLUSH);
  }
  s.host_present = present;
  if (present && (p.revents & POLLIN)) {
    std::uint8_t buf[256];
    const ssize_t n = ::read(s.master, buf, sizeof buf);
    if (n > 0) {
      s.stats.bytes_received += static_cast<std::uint64_t>(n);
      s.commands.feed(std::span<const std::uint8_t>(buf, static_cast<std::size_t>(n)));
    }
  }
}

void VirtualDevice::apply_commands(double now) {
  State& s = *state_;
  while (auto c = s.commands.next()) {
    if (c->kind == tld::HostCommand::Kind::Unknown) {
      ++s.stats.command_garbage;
      continue;
    }
    ++s.stats.commands;
    if (profile_ == FirmwareProfile::kPublished) {
      // Its receive is armed once for two bytes and never again, and the
      // framed decoder is never called: every command is ignored.
      ++s.stats.commands_ignored;
      continue;
    }
    apply_command(*c, now);
  }
  // The parser's byte-level garbage (bytes that start no command), counted
  // since the last look; it grows when feed() sees the bytes.
  s.stats.command_garbage += s.commands.garbage() - s.garbage_seen;
  s.garbage_seen = s.commands.garbage();
}

void VirtualDevice::apply_command(const tld::HostCommand& c, double now) {
  State& s = *state_;
  using K = tld::HostCommand::Kind;
  switch (c.kind) {
    case K::Reset:
    case K::FramedReset:
      s.mode = FirmwareMode::kSingleShot;
      s.shot_pulses = std::clamp((c.value + 5) / 10 * 10, 10, 990);
      s.set.reset();
      s.frames.clear();
      system_->set_emitting(sensor_, false, now);
      break;
    case K::Sample:
    case K::FramedSample:
      if (s.mode == FirmwareMode::kSingleShot) s.shot_requested = true;
      break;
    case K::SampleRestart:
      if (s.mode == FirmwareMode::kSingleShot) {
        s.shot_requested = true;
      } else {
        s.set.reset();  // restart the pulse timers: a new set from now
        s.frames.clear();
      }
      break;
    case K::Laser:
      s.laser = c.value != 0;
      s.set.reset();
      s.frames.clear();
      system_->set_emitting(sensor_, false, now);
      break;
    case K::StreamMode:
      s.mode = c.value == 0 ? FirmwareMode::kDistance : FirmwareMode::kRaw;
      if (s.mode == FirmwareMode::kDistance && !s.onboard)
        s.onboard = factory_calibration(system_->sensor(sensor_).params());
      s.set.reset();
      s.frames.clear();
      break;
    case K::Unknown: break;
  }
}

void VirtualDevice::emit_distance_frame(const SensorSet& set, double now) {
  State& s = *state_;
  if (!s.onboard) s.onboard = factory_calibration(system_->sensor(sensor_).params());
  tld::DistanceFrame f;
  const auto units = firmware_distances(set, *s.onboard);
  for (std::size_t i = 0; i < std::min(units.size(), tld::kPixels); ++i) f.distance[i] = units[i];
  std::vector<std::uint8_t> bytes;
  tld::encode_distance_frame(f, bytes);
  WireTruth truth;
  truth.kind = WireTruth::Kind::kDistanceFrame;
  truth.distance = &f;
  truth.queued = s.host_present && s.tx_bytes + bytes.size() <= options_.tx_buffer_bytes;
  tell_wire(truth, now);
  enqueue(std::move(bytes));
}

void VirtualDevice::tell_wire(WireTruth truth, double now) {
  State& s = *state_;
  truth.sequence = s.frames_made++;
  truth.t_s = now;
  if (s.on_wire) s.on_wire(truth);
}

void VirtualDevice::run_published(double now) {
  State& s = *state_;
  const FirmwareParams& fw = s.published->params();
  const double cycle_s = fw.cycle_s();
  if (now < s.cycle_start + cycle_s) return;
  if (now > s.cycle_start + 10.0 * cycle_s) s.cycle_start = now - cycle_s;  // the thread fell far behind: skip ahead
  // The cycle that just ended: the laser pulsed through the read-out
  // schedule, then the firmware measured the ambient level without it.
  const auto& pulses = system_->sensor(sensor_).params().acquisition.distance_pulses;
  const double t0 = s.cycle_start;
  const double t_dark = t0 + system_->sensor(sensor_).accumulation_time_s(pulses.back());
  system_->set_emitting(sensor_, true, t0);
  system_->set_emitting(sensor_, false, t_dark);
  const SensorSet lit = system_->measure(sensor_, t0, pulses, s.index++, true);
  const SensorSet dark = system_->measure(sensor_, t_dark, pulses, s.index++, false);
  const PublishedCycle cycle = s.published->compute(lit, dark);
  ++s.stats.sets;
  ++s.stats.cycles;
  if (s.on_set) s.on_set(lit);
  system_->notify(sensor_, lit);
  WireTruth truth;
  truth.kind = WireTruth::Kind::kPublishedCycle;
  truth.cycle = &cycle;
  truth.firmware = &*s.published;
  tell_wire(truth, now);
  // The new words go into the buffer the DMA is reading: a frame in flight
  // goes out with its first part old and the rest new.
  tld::DistanceFrame f;
  f.distance = cycle.distance;
  std::vector<std::uint8_t> bytes;
  tld::encode_distance_frame(f, bytes);
  std::copy(bytes.begin(), bytes.end(), s.txbuff.begin());
  if (!s.dma_running) {
    s.dma_running = true;
    s.dma_pos = 0;
    s.last_write_t = now;
  }
  s.cycle_start += cycle_s;
}

void VirtualDevice::run_dma_link(double now) {
  State& s = *state_;
  if (!s.dma_running) {
    s.last_write_t = now;
    return;
  }
  // The UART sends at baud / 10 bytes per second, whether anyone listens or not.
  const double byte_s = 10.0 / options_.baud;
  // A thread that ran late still sends what the UART sent meanwhile (up to a
  // host buffer's worth; beyond it is a suspend, not a link).
  if (now - s.last_write_t > kHostBufferBytes * byte_s) s.last_write_t = now - kHostBufferBytes * byte_s;
  const auto n = static_cast<std::size_t>((now - s.last_write_t) / byte_s);
  if (n == 0) return;
  s.last_write_t += static_cast<double>(n) * byte_s;
  std::vector<std::uint8_t> out(n);
  std::uint64_t frames = 0;
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = s.txbuff[s.dma_pos];
    if (++s.dma_pos == s.txbuff.size()) {
      s.dma_pos = 0;
      ++frames;
    }
  }
  if (!s.host_present) {
    s.stats.bytes_no_host += n;
    s.stats.frames_no_host += frames;
    return;
  }
  if (now < s.stall_until) {
    s.stats.bytes_overrun += n;  // the adapter's buffer overflows while the USB side stalls
    return;
  }
  s.stats.frames_sent += frames;
  write_to_host(apply_faults(out));
}

void VirtualDevice::enqueue(std::vector<std::uint8_t> bytes) {
  State& s = *state_;
  if (!s.host_present) {
    ++s.stats.frames_no_host;
    return;
  }
  if (s.tx_bytes + bytes.size() > options_.tx_buffer_bytes) {
    ++s.stats.frames_overflowed;
    return;
  }
  s.tx_bytes += bytes.size();
  s.tx.push_back(std::move(bytes));
}

void VirtualDevice::begin_set(double t0, const std::vector<int>& pulses) {
  State& s = *state_;
  system_->set_emitting(sensor_, true, t0);
  SensorSet set = system_->measure(sensor_, t0, pulses, s.index++, true);
  ++s.stats.sets;
  if (s.on_set) s.on_set(set);
  system_->notify(sensor_, set);
  s.frames = raw_frames(set);
  s.next_frame = 0;
  s.set = std::move(set);
}

const std::vector<int>& VirtualDevice::streaming_pulses() const {
  const auto& acq = system_->sensor(sensor_).params().acquisition;
  return state_->mode == FirmwareMode::kRaw ? acq.raw_pulses : acq.distance_pulses;
}

void VirtualDevice::run_firmware(double now, double& sleep_s) {
  State& s = *state_;
  // Start a set when due.
  if (!s.set) {
    if (s.mode == FirmwareMode::kSingleShot) {
      if (s.shot_requested) {
        s.shot_requested = false;
        begin_set(now, {s.shot_pulses});
      }
    } else if (s.laser) {
      begin_set(now, streaming_pulses());
    }
  }
  // Read-outs that completed: their frames go to the transmit queue.
  while (s.set) {
    if (!emit_due_frames(now, sleep_s)) break;
    // Set complete: in continuous modes the next one starts where this ended.
    const double t_end = s.set->t_end_s - system_->sensor_time(0.0);
    const bool continuous = s.mode != FirmwareMode::kSingleShot && s.laser;
    s.set.reset();
    if (!continuous) {
      system_->set_emitting(sensor_, false, t_end);
      break;
    }
    begin_set(t_end, streaming_pulses());
  }
}

bool VirtualDevice::emit_due_frames(double now, double& sleep_s) {
  State& s = *state_;
  const SensorSet& set = *s.set;
  if (s.mode == FirmwareMode::kDistance) {
    if (now < set.t_end_s - system_->sensor_time(0.0)) return false;
    emit_distance_frame(set, now);
    return true;
  }
  const double rate = system_->sensor(sensor_).params().emitter.pulse_rate_hz;
  while (s.next_frame < s.frames.size()) {
    const double t_ready = set.t_start_s - system_->sensor_time(0.0) + s.frames[s.next_frame].pulses / rate;
    if (now < t_ready) {
      sleep_s = std::min(sleep_s, t_ready - now);
      return false;
    }
    std::vector<std::uint8_t> bytes;
    tld::encode_raw_frame(s.frames[s.next_frame], bytes);
    WireTruth truth;
    truth.kind = WireTruth::Kind::kRawFrame;
    truth.raw = &s.frames[s.next_frame];
    truth.queued = s.host_present && s.tx_bytes + bytes.size() <= options_.tx_buffer_bytes;
    tell_wire(truth, now);
    enqueue(std::move(bytes));
    ++s.next_frame;
  }
  return true;
}

void VirtualDevice::run_link(double now) {
  State& s = *state_;
  // Pace the queued bytes at baud / 10.
  if (now < s.stall_until || !s.host_present || s.tx.empty()) {
    s.last_write_t = now;
    return;
  }
  double budget = (now - s.last_write_t) * options_.baud / 10.0;
  budget = std::min(budget, 4096.0);
  std::vector<std::uint8_t> out;
  while (budget >= 1.0 && !s.tx.empty()) {
    auto& front = s.tx.front();
    const std::size_t take = std::min<std::size_t>(static_cast<std::size_t>(budget), front.size() - s.tx_offset);
    out.insert(out.end(), front.begin() + static_cast<std::ptrdiff_t>(s.tx_offset),
               front.begin() + static_cast<std::ptrdiff_t>(s.tx_offset + take));
    s.tx_offset += take;
    budget -= static_cast<double>(take);
    if (s.tx_offset == front.size()) {
      s.tx_bytes -= front.size();
      s.tx.pop_front();
      s.tx_offset = 0;
      ++s.stats.frames_sent;
    }
  }
  const double sent_time = static_cast<double>(out.size()) * 10.0 / options_.baud;
  s.last_write_t = std::min(now, s.last_write_t + sent_time);
  write_to_host(apply_faults(out));
}

std::vector<std::uint8_t> VirtualDevice::apply_faults(const std::vector<std::uint8_t>& out) {
  State& s = *state_;
  std::vector<std::uint8_t> wire;
  wire.reserve(out.size());
  for (std::uint8_t b : out) {
    if (s.faults.byte_drop_rate > 0.0 && s.fault_rng.uniform() < s.faults.byte_drop_rate) {
      ++s.stats.bytes_dropped;
      continue;
    }
    if (s.faults.byte_error_rate > 0.0 && s.fault_rng.uniform() < s.faults.byte_error_rate) {
      b ^= static_cast<std::uint8_t>(1u << (s.fault_rng.next() % 8));
      ++s.stats.bytes_corrupted;
    }
    wire.push_back(b);
  }
  return wire;
}

void VirtualDevice::write_to_host(const std::vector<std::uint8_t>& wire) {
  State& s = *state_;
  // Bytes wait in the host's receive buffer (the kernel's, behind the
  // adapter) while the host is slow to read; beyond it the oldest are lost.
  s.to_host.insert(s.to_host.end(), wire.begin(), wire.end());
  if (s.to_host.size() > kHostBufferBytes) {
    const std::size_t lost = s.to_host.size() - kHostBufferBytes;
    s.to_host.erase(s.to_host.begin(), s.to_host.begin() + static_cast<std::ptrdiff_t>(lost));
    s.stats.bytes_overrun += lost;
  }
  flush_to_host();
}

void VirtualDevice::flush_to_host() {
  State& s = *state_;
  std::size_t off = 0;
  while (off < s.to_host.size()) {
    const ssize_t w = ::write(s.master, s.to_host.data() + off, s.to_host.size() - off);
    if (w <= 0) break;  // the pty is full: the rest waits for the host to read
    off += static_cast<std::size_t>(w);
  }
  s.to_host.erase(s.to_host.begin(), s.to_host.begin() + static_cast<std::ptrdiff_t>(off));
  s.stats.bytes_sent += off;
}

}  // namespace tinyline::sim
