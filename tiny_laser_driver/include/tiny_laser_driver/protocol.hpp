// SPDX-License-Identifier: Apache-2.0
// The tiny TOF line sensor's serial framing (the firmware of the real sensor):
// frame layouts, an encoder (used by the simulator's virtual device and by
// tests), a streaming parser (used by the driver) and the host commands.
//
// Core code: no I/O, no bus. Bytes in any chunking go in; complete frames
// and raw sets come out; every byte or frame dropped is counted by reason.
//
// Both kinds of frame share the header and the ender and differ in length
// (548 bytes for distances, 1,096 for raw read-outs); the parser tells them
// apart by where the ender is, so it reads either firmware without being
// told which (a distance frame's ender sits where a raw frame carries A[270],
// which no ADC value can make 0x2B2A).
//
// The framing has no checksum: only the two-byte header and ender guard a
// frame. The parser adds the checks the layout allows without changing it
// (index and pulse fields, set order) and counts pixel values no 12-bit ADC
// can produce, so corruption that slips through the framing is at least
// visible in the diagnostics.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace tinyline::tiny_laser_driver {

inline constexpr std::size_t kPixels = 272;    ///< transmitted pixels per line
inline constexpr std::size_t kDarkPixels = 8;  ///< dark pixels at each end (no range)
inline constexpr std::size_t kReadoutsPerSet = 5;
inline constexpr std::uint8_t kHeader[2] = {0xA2, 0xA1};
inline constexpr std::uint8_t kEnder[2] = {0x2A, 0x2B};
/// Added to the index of a set's last frame. The public driver reads a frame
/// as its set's last when the index word is above 100 (`num > 100`), so a
/// set of one frame (single shot) sends 101, never 100 (last_frame_word()).
inline constexpr std::uint16_t kLastFrameFlag = 100;
inline constexpr std::size_t kDistanceFrameBytes = 2 + kPixels * 2 + 2;     // 548
inline constexpr std::size_t kRawFrameBytes = 2 + 4 + 2 * kPixels * 2 + 2;  // 1096
/// Largest magnitude a raw pixel value can have on the wire: the 12-bit ADC
/// reads 0-4095 tenths of a charge unit, and a discharge is a difference of two.
inline constexpr int kMaxRawMagnitude = 4095;
/// A raw read-out on the wire (RawFrame::a, b; RawScan's a, b) in the
/// sensor's charge unit: the wire carries ten times the unit as int16.
[[nodiscard]] constexpr double charge_units(std::int16_t wire) { return wire / 10.0; }
/// Bits per byte on the wire at 8N1 (start + 8 data + stop).
inline constexpr int kBitsPerByte8N1 = 10;

/// One raw frame: one non-destructive read-out of both capacitors.
struct RawFrame {
  std::uint16_t index = 0;                ///< position within the set (0-based, flag removed)
  bool last = false;                      ///< the sensor marked it as the set's last frame
  std::uint16_t temperature_decic = 0;    ///< MCU temperature [0.1 degC]
  std::uint16_t pulses = 0;               ///< accumulated pulses (a multiple of 10)
  std::array<std::int16_t, kPixels> a{};  ///< capacitor A, ten times the charge unit
  std::array<std::int16_t, kPixels> b{};  ///< capacitor B, ten times the charge unit
  /// Parser only: stream offset just past the frame's last byte (bytes fed
  /// before it), so the caller can time the frame (see Parser::feed).
  std::uint64_t end_byte = 0;
};

/// A complete raw measurement set: frames in index order, the last one flagged.
struct RawSet {
  std::vector<RawFrame> frames;
  /// Parser only: sets seen before this one, complete or not (gaps in it are
  /// sets lost to damage).
  std::uint64_t sequence = 0;

  /// The set's MCU temperature [0.1 degC]: the median of its frames, so one
  /// corrupted packed word cannot move it.
  [[nodiscard]] std::uint16_t temperature_decic() const;
  /// Stream offset just past the set's last byte (0 for an empty set).
  [[nodiscard]] std::uint64_t end_byte() const { return frames.empty() ? 0 : frames.back().end_byte; }
};

/// A distance-only frame (distance computed by the firmware).
struct DistanceFrame {
  /// Per pixel, unsigned, in the firmware's unit (the published firmware:
  /// 0.1 mm, so 0-6.5535 m); 0 = invalid.
  std::array<std::uint16_t, kPixels> distance{};
  std::uint64_t end_byte = 0;  ///< parser only: stream offset just past the frame's last byte
  std::uint64_t sequence = 0;  ///< parser only: frames seen before this one, accepted or dropped
};

/// The two kinds of frame: raw read-outs, or distances the firmware computed.
enum class StreamMode { Raw, Distance };
std::string_view to_string(StreamMode m);

/// The index word a frame carries: its index, plus kLastFrameFlag on the
/// set's last frame; a set of one sends 101 (the public driver needs > 100).
[[nodiscard]] constexpr std::uint16_t last_frame_word(std::uint16_t index, bool last) {
  if (!last) return index;
  return static_cast<std::uint16_t>(index == 0 ? kLastFrameFlag + 1 : index + kLastFrameFlag);
}

/// Bytes on the wire of one frame of the mode.
[[nodiscard]] constexpr std::size_t frame_bytes(StreamMode m) {
  return m == StreamMode::Raw ? kRawFrameBytes : kDistanceFrameBytes;
}
/// Time one byte takes on the wire at `baud` (8N1) [s].
[[nodiscard]] inline double byte_time_s(double baud) { return kBitsPerByte8N1 / baud; }

// ---------------------------------------------------------------------------- encoder

/// Appends one raw frame (1,096 bytes). The index word is last_frame_word();
/// the packed word is temperature_decic * 100 + pulses / 10, so pulses must
/// be a multiple of 10 below 1,000 and the word must fit 16 bits (about
/// 65.5 degC at most). Throws std::invalid_argument otherwise.
void encode_raw_frame(const RawFrame& f, std::vector<std::uint8_t>& out);
/// Appends one distance frame (548 bytes).
void encode_distance_frame(const DistanceFrame& f, std::vector<std::uint8_t>& out);

// ---------------------------------------------------------------------------- parser

enum class DropReason : std::uint8_t {
  kGarbage = 0,    ///< bytes skipped while hunting for a header (counted in bytes)
  kBadEnder,       ///< a frame whose ender was wrong; the hunt resumes after its header
  kBadField,       ///< a frame with an impossible index or pulse field
  kIncompleteSet,  ///< a raw set missing a member, out of order, or with pulses not rising (counted per set)
  kTruncated,      ///< a frame cut short by reset() (e.g. the device went away mid-frame)
  kCount
};
std::string_view to_string(DropReason r);

struct ParserStats {
  /// Per reason: bytes for kGarbage, sets for kIncompleteSet, frames otherwise.
  std::array<std::uint64_t, static_cast<std::size_t>(DropReason::kCount)> drops{};
  std::uint64_t frames = 0;            ///< well-formed frames accepted (some may later fall in an incomplete set)
  std::uint64_t raw_frames = 0;        ///< of those, raw frames
  std::uint64_t distance_frames = 0;   ///< of those, distance frames
  std::uint64_t frames_discarded = 0;  ///< accepted frames thrown away with their incomplete set
  std::uint64_t sets = 0;              ///< raw sets completed
  std::uint64_t bytes = 0;             ///< bytes fed
  /// Raw pixel values no 12-bit ADC can produce (|v| > kMaxRawMagnitude): a
  /// corrupted byte the framing cannot catch. The frame is kept (the driver's
  /// validity rule rejects such a read-out); the count goes to diagnostics.
  std::uint64_t impossible_values = 0;
  [[nodiscard]] std::uint64_t dropped(DropReason r) const { return drops[static_cast<std::size_t>(r)]; }
  /// Frames lost, whatever the reason (garbage bytes and incomplete sets excluded).
  [[nodiscard]] std::uint64_t frames_dropped() const {
    return dropped(DropReason::kBadEnder) + dropped(DropReason::kBadField) + dropped(DropReason::kTruncated);
  }
};

/// Streaming parser of both kinds of frame. Feed bytes in any chunking;
/// complete items are queued and taken with next_set() / next_distance().
/// The output does not depend on how the bytes were split.
///
/// A frame whose ender is wrong is dropped and the hunt resumes one byte
/// after its header, so a header inside the corrupt frame is not missed; the
/// bytes the hunt then skips count as garbage. A raw set is published only
/// whole: frames 0..n-1 in order, the last one flagged, pulses rising. Each
/// set sent is counted once, published or kIncompleteSet, whichever single
/// framing field a bit flip damages (a frame whose index does not rise
/// starts a new set only if its pulses do not rise either).
class Parser {
 public:
  struct Options {
    std::size_t readouts_per_set = kReadoutsPerSet;  ///< frames per raw set, 1-99
  };
  Parser() : Parser(Options{}) {}
  /// Throws std::invalid_argument on readouts_per_set outside 1-99.
  explicit Parser(Options options);

  void feed(std::span<const std::uint8_t> bytes);

  std::optional<RawSet> next_set();
  std::optional<DistanceFrame> next_distance();
  /// Items parsed and not yet taken.
  [[nodiscard]] std::size_t ready() const;

  [[nodiscard]] const ParserStats& stats() const { return stats_; }
  [[nodiscard]] const Options& options() const { return options_; }
  /// Bytes held back: a header byte or a frame not yet complete.
  [[nodiscard]] std::size_t buffered() const { return buf_.size() - start_; }
  /// Frames of the raw set being assembled.
  [[nodiscard]] std::size_t pending_frames() const { return pending_.size(); }

  /// Forgets partial data (after a disconnect): a frame cut short counts as
  /// kTruncated, a half-received set as kIncompleteSet. Items already parsed
  /// stay queued; counters are kept.
  void reset();

 private:
  // Steps of feed().
  void append(std::span<const std::uint8_t> bytes);
  void skip_to_header();  // counts what it skips as garbage
  bool take_frame();      // false: the frame at start_ is not complete yet
  bool accept_frame(std::size_t len);
  bool skip_frame(DropReason why, std::size_t len);
  void consume_distance(const std::uint8_t* frame, std::uint64_t end_byte);
  // Steps of a raw frame's way into a set.
  void consume_frame(const std::uint8_t* frame, std::uint64_t end_byte);
  void place_in_set(std::uint16_t index, std::uint16_t pulses);
  void keep_raw_frame(const std::uint8_t* p, std::uint16_t index, bool last, std::uint16_t packed,
                      std::uint64_t end_byte);
  void close_set();  // after a frame flagged last
  void abandon_pending();
  void drop(DropReason r, std::uint64_t n = 1) { stats_.drops[static_cast<std::size_t>(r)] += n; }

  Options options_;
  std::vector<std::uint8_t> buf_;  // unparsed bytes
  std::size_t start_ = 0;          // first unparsed byte in buf_
  std::uint64_t buf_origin_ = 0;   // stream offset of buf_[0]
  std::vector<RawFrame> pending_;  // frames of the set being assembled
  bool broken_ = false;            // the current set is already counted as incomplete
  int prev_index_ = -1;            // index of the previous frame of the current set (-1: at a set boundary)
  std::uint16_t prev_pulses_ = 0;  // its pulses
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

/// Framed commands: 0xF8 len payload 0x8F, len = payload bytes (code + args).
inline constexpr std::uint8_t kCmdStart = 0xF8;
inline constexpr std::uint8_t kCmdEnd = 0x8F;
enum class FramedCommand : std::uint8_t {
  kReset = 0x01,   ///< int16 pulses (real firmware)
  kSample = 0x02,  ///< int16 (real firmware)
  // tinyline extensions (opt-in; a sensor that does not know them ignores the frame):
  kLaser = 0x10,       ///< uint8 0/1: laser emission off/on (multi-sensor sequence mode, Algorithm 4)
  kStreamMode = 0x11,  ///< uint8 0 distance-only, 1 raw
};
/// Throws std::invalid_argument when code + args exceed 255 bytes.
std::vector<std::uint8_t> cmd_framed(FramedCommand c, std::span<const std::uint8_t> args);
/// 0xF8 0x03 0x01 lo hi 0x8F: reset with a pulse count.
std::vector<std::uint8_t> cmd_framed_reset(std::int16_t pulses);
/// 0xF8 0x02 0x10 on 0x8F.
std::vector<std::uint8_t> cmd_laser(bool on);
/// 0xF8 0x02 0x11 mode 0x8F.
std::vector<std::uint8_t> cmd_stream_mode(StreamMode m);

/// A parsed host command (what the simulator's virtual device receives).
struct HostCommand {
  enum class Kind { Reset, Sample, SampleRestart, FramedReset, FramedSample, Laser, StreamMode, Unknown };
  Kind kind = Kind::Unknown;
  std::int32_t value = 0;  ///< pulses for resets, 0/1 for laser, mode for StreamMode, code for Unknown
};

/// Streaming decoder of host commands, for the device side. A framed command
/// with a wrong end byte is skipped one byte at a time (counted as garbage).
class CommandParser {
 public:
  void feed(std::span<const std::uint8_t> bytes);
  std::optional<HostCommand> next();
  [[nodiscard]] std::uint64_t garbage() const { return garbage_; }

 private:
  std::vector<std::uint8_t> buf_;
  std::vector<HostCommand> out_;
  std::size_t taken_ = 0;
  std::uint64_t garbage_ = 0;
};

}  // namespace tinyline::tiny_laser_driver
