// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/stream_health.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

namespace tinyline::tiny_laser_driver {

// ---------------------------------------------------------------------------- DistanceRepeats

namespace {

using Words = std::array<std::uint16_t, kPixels>;

// Byte-wise: the frame's start is the old content and its end the new one
// (the tear may fall inside a word).
bool torn_between(const Words& frame, const Words& before, const Words& after) {
  const auto* f = reinterpret_cast<const std::uint8_t*>(frame.data());
  const auto* b = reinterpret_cast<const std::uint8_t*>(before.data());
  const auto* a = reinterpret_cast<const std::uint8_t*>(after.data());
  const std::size_t n = sizeof(Words);
  std::size_t prefix = 0;
  while (prefix < n && f[prefix] == b[prefix]) ++prefix;
  std::size_t suffix = 0;
  while (suffix < n && f[n - 1 - suffix] == a[n - 1 - suffix]) ++suffix;
  return prefix + suffix >= n;
}

}  // namespace

std::optional<DistanceRepeats::Fresh> DistanceRepeats::release() {
  std::optional<Fresh> out = held_;
  held_.reset();
  if (out) {
    last_ = out->frame.distance;
    ++stats_.fresh;
  }
  return out;
}

std::optional<DistanceRepeats::Fresh> DistanceRepeats::push(const DistanceFrame& f, std::int64_t stamp_ns) {
  ++stats_.frames;
  ++since_repeat_;
  if (held_) {
    if (f.distance == held_->frame.distance) {  // confirmed by its repeat
      ++stats_.repeats;
      since_repeat_ = 0;
      return release();
    }
    if (last_ && held_->frame.distance != *last_ && torn_between(held_->frame.distance, *last_, f.distance)) {
      ++stats_.torn;  // half the old content, half this one: never a measurement
      held_ = Fresh{f, stamp_ns};
      return std::nullopt;
    }
    std::optional<Fresh> out = release();  // a content sent once (a stream that does not repeat)
    held_ = Fresh{f, stamp_ns};
    return out;
  }
  if (last_ && f.distance == *last_) {
    ++stats_.repeats;
    since_repeat_ = 0;
    return std::nullopt;
  }
  held_ = Fresh{f, stamp_ns};
  if (!repeating()) return release();  // nothing to wait for
  return std::nullopt;
}

std::optional<DistanceRepeats::Fresh> DistanceRepeats::flush(std::int64_t now_ns) {
  if (!held_ || now_ns - held_->stamp_ns < hold_ns_) return std::nullopt;
  return release();
}

void DistanceRepeats::reset() {
  held_.reset();
  last_.reset();
  since_repeat_ = 1 << 20;
}

bool same_readouts(const RawSet& a, const RawSet& b) {
  if (a.frames.size() != b.frames.size()) return false;
  for (std::size_t k = 0; k < a.frames.size(); ++k) {
    const RawFrame& x = a.frames[k];
    const RawFrame& y = b.frames[k];
    if (x.pulses != y.pulses || x.temperature_decic != y.temperature_decic || x.a != y.a || x.b != y.b) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------- StalePixels

const std::array<bool, kPixels>& StalePixels::update(const std::array<std::uint32_t, kPixels>& values) {
  for (std::size_t p = 0; p < kPixels; ++p) {
    run_[p] = values[p] != 0 && values[p] == prev_[p] ? run_[p] + 1 : 0;
  }
  prev_ = values;
  const auto n = static_cast<int>(kPixels);
  auto unchanged = [&](int p) { return run_[static_cast<std::size_t>(p)] >= stale_after_; };
  auto lively = [&](int p) { return values[static_cast<std::size_t>(p)] != 0 && !unchanged(p); };
  stale_.fill(false);
  // Seeds: unchanged pixels with a neighbour whose value moves.
  for (int p = 0; p < n; ++p) {
    if (!unchanged(p)) continue;
    for (int q = std::max(0, p - span_); q <= std::min(n - 1, p + span_) && !stale_[static_cast<std::size_t>(p)]; ++q) {
      if (q != p && lively(q)) stale_[static_cast<std::size_t>(p)] = true;
    }
  }
  // A stuck patch: unchanged pixels next to a flagged one, both ways.
  for (int p = 1; p < n; ++p) {
    if (stale_[static_cast<std::size_t>(p - 1)] && unchanged(p)) stale_[static_cast<std::size_t>(p)] = true;
  }
  for (int p = n - 2; p >= 0; --p) {
    if (stale_[static_cast<std::size_t>(p + 1)] && unchanged(p)) stale_[static_cast<std::size_t>(p)] = true;
  }
  return stale_;
}

int StalePixels::count() const { return static_cast<int>(std::count(stale_.begin(), stale_.end(), true)); }

void StalePixels::reset() {
  prev_.fill(0);
  run_.fill(0);
  stale_.fill(false);
}

void apply_stale(const std::array<bool, kPixels>& stale, ProcessedScan& scan) {
  for (std::size_t p = 0; p < kPixels; ++p) {
    if (!stale[p] || scan.status[p] == PixelStatus::kDarkPixel) continue;
    if (scan.status[p] == PixelStatus::kValid) --scan.valid;
    scan.status[p] = PixelStatus::kStale;
    scan.distance_m[p] = ProcessedScan::kNaN;
    scan.reflectance[p] = ProcessedScan::kNaN;
    ++scan.stale;
  }
}

// ---------------------------------------------------------------------------- RangeShares

void RangeShares::add(const ProcessedScan& scan) {
  for (std::size_t p = 0; p < kPixels; ++p) {
    if (scan.status[p] != PixelStatus::kValid) continue;
    ++valid;
    if (scan.distance_m[p] > max_m) ++beyond;
    if (scan.distance_m[p] < min_m) ++under;
  }
}

std::string RangeShares::verdict() const {
  if (valid < 100) return {};
  const double far = static_cast<double>(beyond) / static_cast<double>(valid);
  const double near = static_cast<double>(under) / static_cast<double>(valid);
  if (far > 0.5)
    return fmt::format("{:.0f}% of the valid pixels are beyond {} m: is distance_unit_m right?", 100 * far, max_m);
  if (near > 0.5)
    return fmt::format("{:.0f}% of the valid pixels are under {} m: is distance_unit_m right?", 100 * near, min_m);
  return {};
}

// ---------------------------------------------------------------------------- CommandWatch

void CommandWatch::laser_sent(bool on, std::int64_t t_ns) {
  if (!on) {
    if (!off_since_) {
      off_since_ = t_ns;
      off_judged_ = false;
      ++laser_off_.sent;
    }
    return;
  }
  if (off_since_ && !off_judged_ && t_ns - *off_since_ > grace_ns_) {
    ++laser_off_.obeyed;  // off for longer than the grace, and nothing measured meanwhile
    laser_off_ignored_last_ = false;
  }
  off_since_.reset();
}

void CommandWatch::stream_mode_sent(StreamMode mode, std::int64_t t_ns) {
  mode_pending_ = std::make_pair(mode, t_ns);
  ++stream_mode_.sent;
}

void CommandWatch::reset_sent(int pulses, std::int64_t t_ns) {
  reset_pending_ = std::make_pair(pulses, t_ns);
  ++reset_.sent;
}

void CommandWatch::measured(StreamMode kind, std::span<const std::uint16_t> pulses, std::int64_t stamp_ns) {
  if (off_since_ && !off_judged_ && stamp_ns > *off_since_ + grace_ns_) {
    ++laser_off_.ignored;  // a measurement read out well after the laser was told off
    off_judged_ = true;
    laser_off_ignored_last_ = true;
  }
  if (mode_pending_ && stamp_ns > mode_pending_->second + grace_ns_) {
    ++(kind == mode_pending_->first ? stream_mode_.obeyed : stream_mode_.ignored);
    mode_pending_.reset();
  }
  if (reset_pending_ && stamp_ns > reset_pending_->second + grace_ns_) {
    const bool took =
        kind == StreamMode::Raw &&
        std::find(pulses.begin(), pulses.end(), static_cast<std::uint16_t>(reset_pending_->first)) != pulses.end();
    ++(took ? reset_.obeyed : reset_.ignored);
    reset_pending_.reset();
  }
}

std::string CommandWatch::summary() const {
  std::string out;
  auto add = [&](const char* name, const Counts& c) {
    if (c.sent == 0) return;
    out +=
        fmt::format("{}{}: sent {}, obeyed {}, ignored {}", out.empty() ? "" : "; ", name, c.sent, c.obeyed, c.ignored);
  };
  add("laser off", laser_off_);
  add("stream mode", stream_mode_);
  add("reset", reset_);
  return out.empty() ? "none sent" : out;
}

}  // namespace tinyline::tiny_laser_driver
