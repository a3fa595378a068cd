// The tiny TOF line sensor's serial framing (reference/wire_protocol.md):
// frame layouts, an encoder (used by the simulator's virtual device and by
// tests), a streaming parser (used by the driver) and the host commands.
//
// Core code: no I/O, no bus. Bytes in any chunking go in; complete frames
// and raw sets come out; every byte or frame dropped is counted by reason.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace tinyline::tiny_laser_driver {

inline constexpr std::size_t kPixels = 272;      ///< transmitted pixels per line
inline constexpr std::size_t kDarkPixels = 8;    ///< dark pixels at each end (no range)
inline constexpr std::size_t kReadoutsPerSet = 5;
inline constexpr std::uint8_t kHeader[2] = {0xA2, 0xA1};
inline constexpr std::uint8_t kEnder[2] = {0x2A, 0x2B};
inline constexpr std::uint16_t kLastFrameFlag = 100;  ///< added to the index of a set's last frame
inline constexpr std::size_t kDistanceFrameBytes = 2 + kPixels * 2 + 2;   // 548
inline constexpr std::size_t kRawFrameBytes = 2 + 4 + 2 * kPixels * 2 + 2;  // 1096

/// One raw frame: one non-destructive read-out of both capacitors.
struct RawFrame {
  std::uint16_t index = 0;        ///< position within the set (0-based, flag removed)
  bool last = false;              ///< the sensor marked it as the set's last frame
  std::uint16_t temperature_decic = 0;  ///< MCU temperature [0.1 degC]
  std::uint16_t pulses = 0;       ///< accumulated pulses (a multiple of 10)
  std::array<std::int16_t, kPixels> a{};  ///< capacitor A, ten times the charge unit
  std::array<std::int16_t, kPixels> b{};  ///< capacitor B, ten times the charge unit
};

/// A complete raw measurement set: frames in index order, the last one flagged.
struct RawSet {
  std::vector<RawFrame> frames;
};

/// A distance-only frame (distance computed by the firmware).
struct DistanceFrame {
  std::array<std::int16_t, kPixels> distance{};  ///< per pixel, sensor units; 0 = invalid
};

enum class StreamMode { Raw, Distance };

// ---------------------------------------------------------------------------- encoder

/// Appends one raw frame (1,096 bytes). Pulses must be a multiple of 10 below
/// 1,000 and the temperature below 65.5 degC: the packed word is
/// temperature_decic * 100 + pulses / 10.
void encode_raw_frame(const RawFrame& f, std::vector<std::uint8_t>& out);
/// Appends one distance frame (548 bytes).
void encode_distance_frame(const DistanceFrame& f, std::vector<std::uint8_t>& out);

// ---------------------------------------------------------------------------- parser

enum class DropReason : std::uint8_t {
  kGarbage = 0,        ///< bytes skipped while hunting for a header
  kBadEnder,           ///< a frame whose ender was wrong (counted once per frame)
  kIncompleteSet,      ///< a raw set missing a member (or frames out of order)
  kBadField,           ///< a frame with an impossible field (pulses 0, index >= set size)
  kCount
};
std::string_view to_string(DropReason r);

struct ParserStats {
  std::array<std::uint64_t, static_cast<std::size_t>(DropReason::kCount)> drops{};  ///< frames (or bytes for kGarbage)
  std::uint64_t frames = 0;   ///< frames accepted
  std::uint64_t sets = 0;     ///< raw sets completed
  std::uint64_t bytes = 0;    ///< bytes consumed
  std::uint64_t dropped(DropReason r) const { return drops[static_cast<std::size_t>(r)]; }
};

/// Streaming parser for one mode. Feed bytes in any chunking; complete items
/// are queued and taken with next_set() / next_distance(). A frame whose ender
/// is wrong is dropped and the hunt resumes one byte after its header, so a
/// header inside the corrupt frame is not missed.
class Parser {
 public:
  struct Options {
    StreamMode mode = StreamMode::Raw;
    std::size_t readouts_per_set = kReadoutsPerSet;
  };
  Parser() : Parser(Options{}) {}
  explicit Parser(Options options);

  void feed(std::span<const std::uint8_t> bytes);

  std::optional<RawSet> next_set();
  std::optional<DistanceFrame> next_distance();

  const ParserStats& stats() const { return stats_; }
  /// Forgets partial data (e.g. after a reconnect); a half-received set is
  /// counted as kIncompleteSet.
  void reset();

 private:
  void consume_frame(std::span<const std::uint8_t> frame);
  void drop(DropReason r, std::uint64_t n = 1) { stats_.drops[static_cast<std::size_t>(r)] += n; }

  Options options_;
  std::vector<std::uint8_t> buf_;   // unparsed bytes
  std::size_t start_ = 0;           // first unparsed byte in buf_
  std::vector<RawFrame> pending_;   // frames of the set being assembled
  bool orphan_ = false;             // inside a set already counted as incomplete
  std::vector<RawSet> sets_;
  std::vector<DistanceFrame> distances_;
  std::size_t sets_taken_ = 0;
  std::size_t distances_taken_ = 0;
  ParserStats stats_;
};

// ---------------------------------------------------------------------------- host commands

/// 'R', n: reset the pixels and set the pulse count to n * 10.
std::vector<std::uint8_t> cmd_reset(std::uint8_t pulses_div10);
/// 'S': sample once.
std::vector<std::uint8_t> cmd_sample();
/// 'P': sample and restart the pulse timers.
std::vector<std::uint8_t> cmd_sample_restart();

/// Framed commands: 0xF8 len payload 0x8F, len = payload bytes.
inline constexpr std::uint8_t kCmdStart = 0xF8;
inline constexpr std::uint8_t kCmdEnd = 0x8F;
enum class FramedCommand : std::uint8_t {
  kReset = 0x01,       ///< int16 pulses (real firmware)
  kSample = 0x02,      ///< int16 (real firmware)
  // tinyline extensions (opt-in; a sensor that does not know them ignores the frame):
  kLaser = 0x10,       ///< uint8 0/1: laser emission off/on (multi-sensor sequence mode, Algorithm 4)
  kStreamMode = 0x11,  ///< uint8 0 distance-only, 1 raw
};
std::vector<std::uint8_t> cmd_framed(FramedCommand c, std::span<const std::uint8_t> args);
std::vector<std::uint8_t> cmd_laser(bool on);
std::vector<std::uint8_t> cmd_stream_mode(StreamMode m);

/// A parsed host command (what the simulator's virtual device receives).
struct HostCommand {
  enum class Kind { Reset, Sample, SampleRestart, FramedReset, FramedSample, Laser, StreamMode, Unknown };
  Kind kind = Kind::Unknown;
  std::int32_t value = 0;  ///< pulses for resets, 0/1 for laser, mode for StreamMode, code for Unknown
};

/// Streaming decoder of host commands, for the device side.
class CommandParser {
 public:
  void feed(std::span<const std::uint8_t> bytes);
  std::optional<HostCommand> next();
  std::uint64_t garbage() const { return garbage_; }

 private:
  std::vector<std::uint8_t> buf_;
  std::vector<HostCommand> out_;
  std::size_t taken_ = 0;
  std::uint64_t garbage_ = 0;
};

}  // namespace tinyline::tiny_laser_driver
