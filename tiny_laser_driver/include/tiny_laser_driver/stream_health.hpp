// SPDX-License-Identifier: Apache-2.0
// What a stream of frames means as measurements, and what it says about the
// sensor, independent of which firmware sends it:
//
//  * DistanceRepeats: the published firmware sends its one frame buffer back
//    to back (circular DMA) while the content changes about 10 times a
//    second, so identical consecutive frames are one measurement, stamped at
//    its first arrival. A frame in flight while the buffer is rewritten goes
//    out half old, half new: in a repeating stream a new content is held
//    until the next frame confirms it (a repeat) or shows it torn (its start
//    equals the previous content and its end the next one).
//  * StalePixels: a pixel whose value has not changed across many fresh
//    measurements while a neighbour's has is stuck (a saturated pixel the
//    firmware does not refresh, a dead pixel): flagged, not trusted.
//  * RangeShares: the share of valid pixels beyond the sensor's range or
//    under its minimum, the sign of a wrong distance unit.
//  * CommandWatch: whether the sensor does what the host's commands ask
//    (the published firmware ignores them all).
//
// Core code: no bus, no I/O. Times are the caller's, in nanoseconds.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include <tiny_laser_driver/protocol.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tinyline::tiny_laser_driver {

struct RepeatStats {
  std::uint64_t frames = 0;   ///< frames seen
  std::uint64_t repeats = 0;  ///< frames equal to the measurement before them (not new)
  std::uint64_t torn = 0;     ///< frames that were half one content, half the next (dropped)
  std::uint64_t fresh = 0;    ///< measurements passed on
};

/// Distance frames to fresh measurements.
class DistanceRepeats {
 public:
  struct Fresh {
    DistanceFrame frame;
    std::int64_t stamp_ns = 0;  ///< the first arrival of its content
  };
  /// `hold_ns`: how long a new content waits for the next frame in a
  /// repeating stream (a few frame times at the link rate).
  explicit DistanceRepeats(std::int64_t hold_ns = 20'000'000) : hold_ns_(hold_ns) {}

  /// A frame that arrived (stamp: when its transmission began). Returns the
  /// measurement this frame lets go, if any.
  [[nodiscard]] std::optional<Fresh> push(const DistanceFrame& f, std::int64_t stamp_ns);
  /// The held content once its hold has run out at `now_ns` (the stream stopped).
  [[nodiscard]] std::optional<Fresh> flush(std::int64_t now_ns);
  /// Forgets the stream (a disconnect); a held content is dropped.
  void reset();
  /// The stream repeats its frames (at least one repeat among the last 16 frames).
  [[nodiscard]] bool repeating() const { return since_repeat_ < 16; }
  [[nodiscard]] const RepeatStats& stats() const { return stats_; }

 private:
  std::optional<Fresh> release();
  std::int64_t hold_ns_;
  std::optional<Fresh> held_;                               // a new content waiting for its confirmation
  std::optional<std::array<std::uint16_t, kPixels>> last_;  // the last content passed on
  int since_repeat_ = 1 << 20;
  RepeatStats stats_;
};

/// True when two raw sets carry the same read-outs (a repeated set).
[[nodiscard]] bool same_readouts(const RawSet& a, const RawSet& b);

/// Per-pixel stuck-value detection over fresh measurements.
class StalePixels {
 public:
  /// `stale_after`: fresh measurements a value may stay unchanged while a
  /// neighbour's (within `span` pixels) changes before it is flagged.
  explicit StalePixels(int stale_after = 20, int span = 2) : stale_after_(stale_after), span_(span) {}
  /// One fresh measurement: a value per pixel (0: none, never stale).
  /// Returns the flags: pixels unchanged that long whose neighbourhood
  /// changed, and the unchanged pixels connected to them (a stuck patch).
  const std::array<bool, kPixels>& update(const std::array<std::uint32_t, kPixels>& values);
  [[nodiscard]] const std::array<bool, kPixels>& flags() const { return stale_; }
  [[nodiscard]] int count() const;
  void reset();

 private:
  int stale_after_, span_;
  std::array<std::uint32_t, kPixels> prev_{};
  std::array<int, kPixels> run_{};  // consecutive fresh measurements with the same non-zero value
  std::array<bool, kPixels> stale_{};
};

/// Marks the flagged pixels of a processed scan as kStale (no distance).
void apply_stale(const std::array<bool, kPixels>& stale, ProcessedScan& scan);

/// Valid pixels of many scans against the sensor's range (0.05-2 m).
struct RangeShares {
  double min_m = 0.05, max_m = 2.0;
  std::uint64_t valid = 0, beyond = 0, under = 0;
  void add(const ProcessedScan& scan);
  /// Empty when plausible; else what is wrong, e.g. "83% of the valid pixels
  /// are beyond 2 m: is distance_unit_m right?". Needs 100 valid pixels.
  [[nodiscard]] std::string verdict() const;
};

/// Whether commands are obeyed, judged from what the stream does after them.
class CommandWatch {
 public:
  /// `grace_ns`: what may still arrive after a command (frames in flight).
  explicit CommandWatch(std::int64_t grace_ns = 100'000'000) : grace_ns_(grace_ns) {}

  void laser_sent(bool on, std::int64_t t_ns);
  void stream_mode_sent(StreamMode mode, std::int64_t t_ns);
  /// A pulse-count reset ('R', n or the framed reset), n in pulses.
  void reset_sent(int pulses, std::int64_t t_ns);
  /// A fresh measurement whose read-out ended at `stamp_ns`: its kind and (raw) its read-outs' pulses.
  void measured(StreamMode kind, std::span<const std::uint16_t> pulses, std::int64_t stamp_ns);

  struct Counts {
    std::uint64_t sent = 0, obeyed = 0, ignored = 0;  ///< the rest is undecided (too short to tell)
  };
  [[nodiscard]] const Counts& laser_off() const { return laser_off_; }
  [[nodiscard]] const Counts& stream_mode() const { return stream_mode_; }
  [[nodiscard]] const Counts& reset() const { return reset_; }
  /// The last laser-off was ignored (measurements kept coming).
  [[nodiscard]] bool ignores_laser_off() const { return laser_off_ignored_last_; }
  /// "laser off: ignored 3 of 4; stream mode: obeyed 1 of 1" (commands sent only).
  [[nodiscard]] std::string summary() const;

 private:
  std::int64_t grace_ns_;
  std::optional<std::int64_t> off_since_;  // laser off pending judgement
  bool off_judged_ = false;
  std::optional<std::pair<StreamMode, std::int64_t>> mode_pending_;
  std::optional<std::pair<int, std::int64_t>> reset_pending_;
  bool laser_off_ignored_last_ = false;
  Counts laser_off_, stream_mode_, reset_;
};

}  // namespace tinyline::tiny_laser_driver
