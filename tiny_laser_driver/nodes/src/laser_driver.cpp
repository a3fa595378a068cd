// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/nodes/laser_driver.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include <fmt/format.h>
#include <tinyline/bus/files.hpp>

#include <tinyline/bus/param_table.hpp>

#include <tiny_laser_driver/nodes/param_tables.hpp>
#include <tiny_laser_driver/public_driver_sensors.hpp>

namespace tinyline::tiny_laser_driver {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

constexpr std::size_t kReadChunk = 16384;

std::string drop_key(DropReason r) { return fmt::format("drops_{}", to_string(r)); }

}  // namespace

// ---------------------------------------------------------------------------- calibration

std::string default_calibration_path() {
  const std::string rel = "tiny_laser_driver/calibration/sim_tiny_tof_8mm.yaml";
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed = exe.parent_path().parent_path() / "share/tinyline" / rel;
    if (fs::exists(installed, ec)) return installed.string();
  }
  return std::string(TINYLINE_DRIVER_CONFIG_DIR) + "/calibration/sim_tiny_tof_8mm.yaml";
}

CalibrationModel load_calibration(const std::string& spec) {
  if (spec.rfind("public:", 0) == 0) {
    const std::string name = spec.substr(7);
    if (auto m = public_driver_calibration(name)) return std::move(*m);
    throw std::runtime_error(fmt::format("calibration '{}': the public driver has no sensor '{}' (it has {})", spec,
                                         name, fmt::join(public_driver_sensor_names(), ", ")));
  }
  const std::string path = spec == "default" ? default_calibration_path() : spec;
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    throw std::runtime_error(fmt::format(
        "calibration '{}': no file {}. Give `calibration:` a YAML written by `tinyline calib fit`, or public:NAME "
        "for a sensor of the public driver ({})",
        spec, path, fmt::join(public_driver_sensor_names(), ", ")));
  }
  // A regular file of bounded size (a FIFO would block, a device never end);
  // from_yaml throws naming the file, line and field.
  return CalibrationModel::from_yaml(files::read_text(path, "calibration file", kMaxCalibrationFileBytes), path);
}

// ---------------------------------------------------------------------------- node

void LaserDriver::declare_params() {
  bus::declare_params(*this, params_);  // the table: tiny_laser_driver/nodes/param_tables.hpp
  require_valid(params_.optics.validate().within("optics"));
}

LaserDriver::LaserDriver(bus::NodeOptions options) : Node(std::move(options)) {
  declare_params();
  DriverParams& p = params_;
  if (p.reconnect_max_s < p.reconnect_min_s) {
    throw bus::ParamError({}, fmt::format("node '{}': reconnect_max_s ({}) is below reconnect_min_s ({})", full_name(),
                                          p.reconnect_max_s, p.reconnect_min_s));
  }
  if (p.sensor_name.empty()) p.sensor_name = name();
  if (p.scan_frame_id.empty()) p.scan_frame_id = p.frame_id + "_scan";
  if (p.mode != "auto") expected_ = p.mode == "raw" ? StreamMode::Raw : StreamMode::Distance;
  // A new content waits for the next frame at most two frame times and the
  // adapter's latency; commands may see a set or two already under way.
  const double byte_s = byte_time_s(p.baud);
  repeats_ = DistanceRepeats(bus::from_seconds(2 * kDistanceFrameBytes * byte_s + 0.02).count());
  watch_ = CommandWatch(bus::from_seconds(2 * kReadoutsPerSet * kRawFrameBytes * byte_s + 0.02).count());
  stale_ = StalePixels(p.stale_after);

  io::PortOptions po;
  po.serial.baud = p.baud;
  po.laser_on_at_start = p.sequence_slot < 0;
  try {
    opener_ = io::make_port_opener(p.port, po);  // parses the spec; opens nothing
  } catch (const std::invalid_argument& e) {     // named at the line that set it (a sim: port's scene is checked here)
    const auto& ps = parameters();
    const auto port = std::find_if(ps.begin(), ps.end(), [](const auto& d) { return d.name == "port"; });
    throw bus::ParamError(port != ps.end() ? port->set_from : bus::SourceLocation{},
                          fmt::format("node '{}': parameter 'port': {}", full_name(), e.what()));
  }
  parser_ = Parser(Parser::Options{static_cast<std::size_t>(p.readouts_per_set)});
  buf_.resize(kReadChunk);
  if (p.sequence_slot >= 0) laser_wanted_ = false;  // sequence mode: off until the sequencer says otherwise
  backoff_s_ = p.reconnect_min_s;

  if (p.publish_raw) raw_pub_ = create_publisher<tinyline_msgs::msg::RawScan>("raw", bus::QoS::sensor_data());
  scan_pub_ = create_publisher<tinyline_msgs::msg::LineScan>("scan", bus::QoS::sensor_data());
  laser_scan_pub_ = create_publisher<sensor_msgs::msg::LaserScan>("laser_scan", bus::QoS::sensor_data());
  if (p.publish_cloud) cloud_pub_ = create_publisher<sensor_msgs::msg::PointCloud2>("cloud", bus::QoS::sensor_data());
  diag_pub_ = create_publisher<diagnostic_msgs::msg::DiagnosticArray>("/diagnostics", bus::QoS::keep_last(10));
  command_sub_ = create_subscription<tinyline_msgs::msg::LaserCommand>(
      "laser_command", bus::QoS::keep_last(10), [this](const tinyline_msgs::msg::LaserCommand& m) { on_command(m); });
  diag_timer_ = create_timer(bus::from_seconds(p.diagnostics_period_s), [this] { publish_diagnostics(); });
}

LaserDriver::~LaserDriver() { on_stop(); }

bus::ParamConstraints calibration_file_constraints() {
  return bus::ParamConstraints::input_file(
      kMaxCalibrationFileBytes,
      std::vector<std::string>(std::begin(kCalibrationNotAFile), std::end(kCalibrationNotAFile)));
}

// Before any node starts (and in `launch --check`): a bad calibration stops
// the launch at its file, line and field before anything else has run.
void LaserDriver::on_configure() {
  if (processor_) return;
  // Raw sets need the calibration; a sensor that sends distances never uses it.
  CalibrationModel model = load_calibration(params_.calibration);
  if (!model.extra_covariates().empty()) {
    logger().warn("the calibration's terms in {} use covariates the driver does not measure; they are skipped",
                  fmt::join(model.extra_covariates(), ", "));
  }
  processor_ = std::make_unique<ScanProcessor>(std::move(model), params_.optics);
  messages_ = std::make_unique<ScanMessages>(*processor_, params_.frame_id, params_.scan_frame_id);
}

void LaserDriver::on_start() {
  if (io_thread_.joinable()) return;
  on_configure();  // when used without an executor
  logger().info("port {} (expecting {} frames; raw sets with calibration {}, distances in units of {} m), frame {}",
                opener_->describe(), params_.mode == "auto" ? "raw or distance" : params_.mode, params_.calibration,
                params_.distance_unit_m, params_.frame_id);
  if (params_.threaded) {
    stop_.store(false);
    io_thread_ = std::thread([this] { run(); });
  }
}

void LaserDriver::on_stop() {
  stop_.store(true);
  {
    std::lock_guard lk(stream_mu_);
    if (stream_) stream_->interrupt();
  }
  wake_.notify_all();
  if (io_thread_.joinable()) io_thread_.join();
  std::lock_guard lk(stream_mu_);
  stream_.reset();
}

void LaserDriver::run() {
  while (!stop_.load()) {
    try {
      pump(50ms);
    } catch (const std::exception& e) {
      // Nothing a device sends may stop the driver; log and carry on.
      logger().error("I/O step failed: {}", e.what());
      std::unique_lock lk(mu_);
      wake_.wait_for(lk, 100ms, [this] { return stop_.load(); });
    }
  }
}

void LaserDriver::pump(std::chrono::milliseconds timeout) {
  if (!processor_) throw std::logic_error("LaserDriver::pump() before on_start()");
  if (!stream_) {
    const bus::Time now = this->now();
    if (now < next_attempt_) {
      if (timeout.count() > 0) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(next_attempt_ - now) + 1ms;
        std::unique_lock lk(mu_);
        wake_.wait_for(lk, std::min(timeout, left), [this] { return stop_.load(); });
      }
      return;
    }
    try_open(now);
    if (!stream_) return;
  }
  send_pending();
  if (!stream_) return;
  // While a new content waits for its confirmation, look again soon.
  const io::ReadResult r = stream_->read(buf_, std::min(timeout, std::chrono::milliseconds(10)));
  const bus::Time t_recv = this->now();
  if (!r.status.ok()) {
    lost(r.status);
    return;
  }
  if (r.bytes > 0) {
    parser_.feed({buf_.data(), r.bytes});
    const std::uint64_t chunk_end = parser_.stats().bytes;
    {
      std::lock_guard lk(mu_);
      status_.bytes += r.bytes;
      status_.last_receive = t_recv;
      status_.parser = parser_.stats();
    }
    while (auto s = parser_.next_set()) take_set(*s, chunk_end, t_recv);
    while (auto d = parser_.next_distance()) take_distance(*d, chunk_end, t_recv);
  }
  // A new content with no next frame to confirm it: the stream stopped or does not repeat.
  if (auto f = repeats_.flush(t_recv.ns)) publish_distance(*f);
  std::lock_guard lk(mu_);
  status_.distance_repeats = repeats_.stats();
}

void LaserDriver::try_open(bus::Time now) {
  io::OpenResult r = opener_->open();
  if (!r.status.ok()) {
    next_attempt_ = now + bus::from_seconds(backoff_s_);
    backoff_s_ = std::min(2.0 * backoff_s_, params_.reconnect_max_s);
    bool changed = false;
    {
      std::lock_guard lk(mu_);
      changed = status_.last_error != r.status.error || status_.last_error_message != r.status.message;
      status_.last_error = r.status.error;
      status_.last_error_message = r.status.message;
      ++status_.open_failures;
    }
    // Say it once per distinct failure, not at every retry.
    if (changed) logger().warn("{} (retrying every {} s at most)", r.status.message, params_.reconnect_max_s);
    return;
  }
  {
    std::lock_guard lk(stream_mu_);
    stream_ = std::move(r.stream);
  }
  backoff_s_ = params_.reconnect_min_s;
  {
    std::lock_guard lk(mu_);
    status_.connected = true;
    status_.connected_at = now;
    ++status_.connects;
    status_.link = stream_->describe();
    status_.last_error = io::IoError::kNone;
    status_.last_error_message.clear();
    if (laser_wanted_) laser_dirty_ = true;  // a replugged sensor forgot what it was told
  }
  logger().info("connected: {}", stream_->describe());
  if (params_.send_stream_mode && expected_) {
    if (const auto st = stream_->write(cmd_stream_mode(*expected_)); !st.ok()) {
      lost(st);
      return;
    }
    watch_.stream_mode_sent(*expected_, this->now().ns);
    std::lock_guard lk(mu_);
    ++status_.commands_sent;
  }
}

void LaserDriver::lost(const io::IoStatus& why) {
  parser_.reset();  // a frame or set cut here is counted, never published
  repeats_.reset();
  last_set_.reset();
  {
    std::lock_guard lk(stream_mu_);
    stream_.reset();
  }
  next_attempt_ = now() + bus::from_seconds(params_.reconnect_min_s);
  backoff_s_ = std::min(2.0 * params_.reconnect_min_s, params_.reconnect_max_s);
  {
    std::lock_guard lk(mu_);
    status_.connected = false;
    ++status_.disconnects;
    status_.last_error = why.error;
    status_.last_error_message = why.message;
    status_.parser = parser_.stats();
  }
  logger().warn("lost the sensor: {}; reconnecting", why.message);
}

void LaserDriver::send_pending() {
  bool want = true;
  {
    std::lock_guard lk(mu_);
    if (!laser_dirty_ || !laser_wanted_) return;
    want = *laser_wanted_;
  }
  if (const auto st = stream_->write(cmd_laser(want)); !st.ok()) {
    lost(st);
    return;
  }
  watch_.laser_sent(want, now().ns);
  std::lock_guard lk(mu_);
  if (laser_wanted_ == want) laser_dirty_ = false;
  status_.laser_on = want;
  ++status_.commands_sent;
}

void LaserDriver::on_command(const tinyline_msgs::msg::LaserCommand& cmd) {
  std::optional<bool> want;
  if (cmd.sensors.size() != cmd.laser_on.size()) {
    logger().warn("LaserCommand with {} sensors and {} laser_on entries: the by-name orders are ignored",
                  cmd.sensors.size(), cmd.laser_on.size());
  } else {
    for (std::size_t i = 0; i < cmd.sensors.size(); ++i) {
      if (cmd.sensors[i] == params_.sensor_name) want = cmd.laser_on[i];
    }
  }
  if (!want && params_.sequence_slot >= 0) {
    want = std::find(cmd.active_slots.begin(), cmd.active_slots.end(), params_.sequence_slot) != cmd.active_slots.end();
  }
  if (!want) return;
  {
    std::lock_guard lk(mu_);
    if (laser_wanted_ == want && !laser_dirty_) return;
    laser_wanted_ = want;
    laser_dirty_ = true;
  }
  {
    std::lock_guard lk(stream_mu_);
    if (stream_ && params_.threaded) stream_->interrupt();  // the I/O thread sends it now, not after its read
  }
  wake_.notify_all();
}

bus::Time LaserDriver::stamp_of(std::uint64_t end_byte, std::uint64_t chunk_end, bus::Time t_recv,
                                StreamMode kind) const {
  // The chunk's last byte arrived at t_recv; earlier ones one byte time apart.
  const double baud = stream_ && stream_->baud() > 0 ? stream_->baud() : params_.baud;
  const double byte_s = byte_time_s(baud);
  const double behind = static_cast<double>(chunk_end - end_byte) * byte_s;
  const double transmission = static_cast<double>(frame_bytes(kind)) * byte_s;
  return t_recv - bus::from_seconds(behind + transmission);
}

void LaserDriver::take_set(const RawSet& set, std::uint64_t chunk_end, bus::Time t_recv) {
  if (last_set_ && same_readouts(*last_set_, set)) {  // sent again: not a new measurement
    std::lock_guard lk(mu_);
    ++status_.raw_repeats;
    return;
  }
  last_set_ = set;
  const bus::Time stamp = stamp_of(set.end_byte(), chunk_end, t_recv, StreamMode::Raw);
  if (!first_stamp_) first_stamp_ = stamp;
  processor_->process(set, (stamp - *first_stamp_).count() * 1e-9, scan_);
  // A valid pixel's distance, to the bit: a stuck read-out repeats it exactly,
  // noise never does (a saturated read-out's constant value is not a distance).
  std::array<std::uint32_t, kPixels> values{};
  for (std::size_t p = 0; p < kPixels; ++p) {
    if (scan_.status[p] == PixelStatus::kValid) values[p] = std::bit_cast<std::uint32_t>(scan_.distance_m[p]);
  }
  apply_stale(stale_.update(values), scan_);
  std::array<std::uint16_t, 128> pulses{};
  const std::size_t n = std::min(set.frames.size(), pulses.size());
  for (std::size_t k = 0; k < n; ++k) pulses[k] = set.frames[k].pulses;
  watch_.measured(StreamMode::Raw, {pulses.data(), n}, stamp.ns);
  if (raw_pub_) raw_pub_->publish(to_raw_scan(set, stamp, params_.frame_id));
  publish_scan(scan_, static_cast<std::uint32_t>(set.sequence), stamp,
               static_cast<float>(set.temperature_decic() / 10.0));
}

void LaserDriver::take_distance(const DistanceFrame& f, std::uint64_t chunk_end, bus::Time t_recv) {
  const bus::Time stamp = stamp_of(f.end_byte, chunk_end, t_recv, StreamMode::Distance);
  if (auto fresh = repeats_.push(f, stamp.ns)) publish_distance(*fresh);
}

void LaserDriver::publish_distance(const DistanceRepeats::Fresh& fresh) {
  processor_->process_distance(fresh.frame, params_.distance_unit_m, scan_);
  std::array<std::uint32_t, kPixels> values{};
  for (std::size_t p = 0; p < kPixels; ++p) values[p] = fresh.frame.distance[p];
  apply_stale(stale_.update(values), scan_);
  watch_.measured(StreamMode::Distance, {}, fresh.stamp_ns);
  {
    std::lock_guard lk(mu_);
    status_.ranges.add(scan_);
  }
  publish_scan(scan_, static_cast<std::uint32_t>(fresh.frame.sequence), bus::Time::from_ns(fresh.stamp_ns),
               std::numeric_limits<float>::quiet_NaN());
}

void LaserDriver::publish_scan(const ProcessedScan& scan, std::uint32_t index, bus::Time stamp, float temperature_c) {
  if (prev_stamp_) scan_period_s_ = (stamp - *prev_stamp_).count() * 1e-9;
  prev_stamp_ = stamp;
  scan_pub_->publish(messages_->line(scan, index, stamp, temperature_c));
  laser_scan_pub_->publish(messages_->laser(scan, stamp, scan_period_s_));
  if (cloud_pub_) cloud_pub_->publish(messages_->cloud(scan, stamp));
  constexpr double kEffective = kPixels - 2 * kDarkPixels;
  std::lock_guard lk(mu_);
  ++status_.scans_published;
  status_.last_scan_stamp = stamp;
  status_.last_saturated_share = scan.saturated_share();
  status_.last_valid_share = scan.valid / kEffective;
  status_.last_stale_pixels = scan.stale;
  status_.commands = watch_.summary();
  status_.ignores_laser_off = watch_.ignores_laser_off();
  if (std::isfinite(temperature_c)) status_.last_temperature_c = temperature_c;
}

DriverStatus LaserDriver::status() const {
  std::lock_guard lk(mu_);
  return status_;
}

namespace {

std::string kinds_seen(const ParserStats& p) {
  if (p.raw_frames > 0 && p.distance_frames > 0) return "raw and distance";
  if (p.raw_frames > 0) return "raw";
  if (p.distance_frames > 0) return "distance";
  return "none yet";
}

// Frames of a kind other than the one expected, as a sentence; empty when none came.
std::string unexpected_kind(const std::optional<StreamMode>& expected, const ParserStats& p) {
  if (!expected) return {};
  const std::uint64_t other = *expected == StreamMode::Raw ? p.distance_frames : p.raw_frames;
  if (other == 0) return {};
  return fmt::format("expected {} frames, the sensor sends {} frames ({}): reading them anyway", to_string(*expected),
                     to_string(*expected == StreamMode::Raw ? StreamMode::Distance : StreamMode::Raw), other);
}

}  // namespace

void LaserDriver::publish_diagnostics() {
  DriverStatus s = status();
  {
    std::lock_guard lk(mu_);
    status_.ranges = RangeShares{};  // the unit check looks at one period at a time
  }
  const bus::Time now = this->now();
  const double dt = diag_have_prev_ ? (now - diag_prev_time_).count() * 1e-9 : 0.0;
  const DriverStatus prev = diag_have_prev_ ? diag_prev_ : DriverStatus{};
  diagnostic_msgs::msg::DiagnosticStatus st;
  st.name = full_name() + ": tiny laser link";
  st.hardware_id = opener_->hardware_id();
  diagnose_level(s, prev, dt, st);
  diagnose_values(s, prev, dt, st);
  auto arr = std::make_unique<diagnostic_msgs::msg::DiagnosticArray>();
  arr->header.stamp = now.to_msg();
  arr->status.push_back(std::move(st));
  diag_pub_->publish(std::move(arr));
  diag_prev_ = s;
  diag_prev_time_ = now;
  diag_have_prev_ = true;
}

void LaserDriver::diagnose_level(const DriverStatus& s, const DriverStatus& prev, double dt,
                                 diagnostic_msgs::msg::DiagnosticStatus& st) const {
  using diagnostic_msgs::msg::DiagnosticStatus;
  std::uint64_t period_drops = 0;
  for (std::size_t r = 0; r < static_cast<std::size_t>(DropReason::kCount); ++r) {
    if (static_cast<DropReason>(r) == DropReason::kGarbage) continue;
    period_drops += s.parser.drops[r] - prev.parser.drops[r];
  }
  // Silence counts from the last byte of this connection, or from the connect
  // when none came yet (last_receive is then unset or of an earlier one).
  const bool heard = s.bytes > 0 && s.last_receive >= s.connected_at;
  const double since_data_s = (now() - (heard ? s.last_receive : s.connected_at)).count() * 1e-9;
  const bool silent = since_data_s > params_.stall_timeout_s;
  const bool frames_but_nothing_new =
      dt > 0 && s.parser.frames > prev.parser.frames && s.scans_published == prev.scans_published;
  std::vector<std::string> warnings;
  if (const auto m = unexpected_kind(expected_, s.parser); !m.empty()) warnings.push_back(m);
  if (const auto m = s.ranges.verdict(); !m.empty()) warnings.push_back(m);
  if (s.ignores_laser_off) warnings.push_back("the sensor ignores laser off: treat it as always emitting");
  if (frames_but_nothing_new) warnings.push_back(fmt::format("frames keep coming but none was new for {:.1f} s", dt));
  if (period_drops > 0)
    warnings.push_back(fmt::format("{} frames or sets dropped in the last {:.1f} s", period_drops, dt));
  if (!s.connected) {
    st.level = DiagnosticStatus::ERROR;
    st.message = s.last_error_message.empty() ? "connecting" : "no device: " + s.last_error_message;
  } else if (silent) {
    st.level = DiagnosticStatus::WARN;
    st.message = fmt::format("connected, but no data for {:.1f} s", since_data_s);
  } else if (!heard) {
    st.level = DiagnosticStatus::OK;
    st.message = "connected, waiting for data";
  } else if (!warnings.empty()) {
    st.level = DiagnosticStatus::WARN;
    st.message = fmt::format("streaming; {}", fmt::join(warnings, "; "));
  } else {
    st.level = DiagnosticStatus::OK;
    st.message = "streaming";
  }
}

void LaserDriver::diagnose_values(const DriverStatus& s, const DriverStatus& prev, double dt,
                                  diagnostic_msgs::msg::DiagnosticStatus& st) const {
  auto per_s = [&](std::uint64_t a, std::uint64_t b) { return dt > 0 ? static_cast<double>(a - b) / dt : 0.0; };
  const double bytes_per_s = per_s(s.bytes, prev.bytes);
  const std::uint64_t frames = s.parser.frames - prev.parser.frames;
  const std::uint64_t repeats =
      (s.distance_repeats.repeats - prev.distance_repeats.repeats) + (s.raw_repeats - prev.raw_repeats);
  auto kv = [&](std::string k, std::string v) {
    st.values.push_back(diagnostic_msgs::msg::KeyValue{std::move(k), std::move(v)});
  };
  kv("state", s.connected ? "connected" : "disconnected");
  kv("port", opener_->describe());
  kv("link", s.link);
  kv("mode", params_.mode);
  kv("frame_kinds", kinds_seen(s.parser));
  kv("frames_per_s", fmt::format("{:.2f}", per_s(s.parser.frames, prev.parser.frames)));
  kv("fresh_per_s", fmt::format("{:.2f}", per_s(s.scans_published, prev.scans_published)));
  kv("frame_rate_hz", fmt::format("{:.2f}", per_s(s.scans_published, prev.scans_published)));
  kv("repeat_share",
     fmt::format("{:.3f}", frames > 0 ? static_cast<double>(repeats) / static_cast<double>(frames) : 0.0));
  kv("repeats", std::to_string(s.distance_repeats.repeats + s.raw_repeats));
  kv("torn_frames", std::to_string(s.distance_repeats.torn));
  kv("bytes_per_s", fmt::format("{:.0f}", bytes_per_s));
  kv("link_utilisation", fmt::format("{:.3f}", bytes_per_s * kBitsPerByte8N1 / params_.baud));
  kv("scans_published", std::to_string(s.scans_published));
  kv("sets_complete", std::to_string(s.parser.sets));
  for (std::size_t r = 0; r < static_cast<std::size_t>(DropReason::kCount); ++r) {
    kv(drop_key(static_cast<DropReason>(r)), std::to_string(s.parser.drops[r]));
  }
  kv("frames_discarded", std::to_string(s.parser.frames_discarded));
  kv("impossible_values", std::to_string(s.parser.impossible_values));
  kv("saturated_share", fmt::format("{:.4f}", s.last_saturated_share));
  kv("valid_share", fmt::format("{:.4f}", s.last_valid_share));
  kv("stale_pixels", std::to_string(s.last_stale_pixels));
  kv("distance_unit_m", fmt::format("{}", params_.distance_unit_m));
  const std::string unit = s.ranges.verdict();
  kv("distance_unit_check", s.ranges.valid < 100 ? "too few distance pixels to tell"
                            : unit.empty()       ? "plausible"
                                                 : unit);
  kv("temperature_c", fmt::format("{:.1f}", s.last_temperature_c));
  kv("connects", std::to_string(s.connects));
  kv("disconnects", std::to_string(s.disconnects));
  kv("open_failures", std::to_string(s.open_failures));
  kv("laser", s.laser_on ? (*s.laser_on ? "on" : "off") : "not commanded");
  kv("commands_sent", std::to_string(s.commands_sent));
  kv("commands", s.commands.empty() ? "none sent" : s.commands);
  kv("laser_off_obeyed", s.ignores_laser_off ? "no" : "yes or untested");
  kv("last_error", s.last_error_message);
}

}  // namespace tinyline::tiny_laser_driver
