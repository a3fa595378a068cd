// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/protocol.hpp>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace tinyline::tiny_laser_driver {

namespace {

void put_u16(std::vector<std::uint8_t>& out, std::uint16_t v) {
  out.push_back(static_cast<std::uint8_t>(v & 0xFF));
  out.push_back(static_cast<std::uint8_t>(v >> 8));
}

std::uint16_t get_u16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (static_cast<std::uint16_t>(p[1]) << 8));
}

void put_i16_array(std::vector<std::uint8_t>& out, const std::array<std::int16_t, kPixels>& v) {
  for (std::int16_t x : v) put_u16(out, static_cast<std::uint16_t>(x));
}

void put_u16_array(std::vector<std::uint8_t>& out, const std::array<std::uint16_t, kPixels>& v) {
  for (std::uint16_t x : v) put_u16(out, x);
}

void get_i16_array(const std::uint8_t* p, std::array<std::int16_t, kPixels>& v) {
  for (std::size_t i = 0; i < kPixels; ++i) v[i] = static_cast<std::int16_t>(get_u16(p + 2 * i));
}

void get_u16_array(const std::uint8_t* p, std::array<std::uint16_t, kPixels>& v) {
  for (std::size_t i = 0; i < kPixels; ++i) v[i] = get_u16(p + 2 * i);
}

}  // namespace

std::string_view to_string(DropReason r) {
  switch (r) {
    case DropReason::kGarbage: return "garbage_bytes";
    case DropReason::kBadEnder: return "bad_ender";
    case DropReason::kBadField: return "bad_field";
    case DropReason::kIncompleteSet: return "incomplete_set";
    case DropReason::kTruncated: return "truncated";
    case DropReason::kCount: break;
  }
  return "?";
}

std::string_view to_string(StreamMode m) { return m == StreamMode::Raw ? "raw" : "distance"; }

std::uint16_t RawSet::temperature_decic() const {
  if (frames.empty()) return 0;
  std::array<std::uint16_t, 128> t{};
  const std::size_t n = std::min(frames.size(), t.size());
  for (std::size_t i = 0; i < n; ++i) t[i] = frames[i].temperature_decic;
  std::nth_element(t.begin(), t.begin() + static_cast<std::ptrdiff_t>(n / 2),
                   t.begin() + static_cast<std::ptrdiff_t>(n));
  return t[n / 2];
}

void encode_raw_frame(const RawFrame& f, std::vector<std::uint8_t>& out) {
  if (f.pulses % 10 != 0 || f.pulses / 10 > 99) {
    throw std::invalid_argument("raw frame pulses must be a multiple of 10 below 1000");
  }
  const std::uint32_t packed = static_cast<std::uint32_t>(f.temperature_decic) * 100 + f.pulses / 10;
  if (packed > 0xFFFF)
    throw std::invalid_argument("raw frame temperature too high for the packed word (about 65.5 degC)");
  if (f.index >= kLastFrameFlag) throw std::invalid_argument("raw frame index must be below 100");
  out.reserve(out.size() + kRawFrameBytes);
  out.insert(out.end(), std::begin(kHeader), std::end(kHeader));
  put_u16(out, last_frame_word(f.index, f.last));
  put_u16(out, static_cast<std::uint16_t>(packed));
  put_i16_array(out, f.a);
  put_i16_array(out, f.b);
  out.insert(out.end(), std::begin(kEnder), std::end(kEnder));
}

void encode_distance_frame(const DistanceFrame& f, std::vector<std::uint8_t>& out) {
  out.reserve(out.size() + kDistanceFrameBytes);
  out.insert(out.end(), std::begin(kHeader), std::end(kHeader));
  put_u16_array(out, f.distance);
  out.insert(out.end(), std::begin(kEnder), std::end(kEnder));
}

// ---------------------------------------------------------------------------- Parser

Parser::Parser(Options options) : options_(options) {
  if (options_.readouts_per_set == 0 || options_.readouts_per_set >= kLastFrameFlag) {
    throw std::invalid_argument("readouts_per_set must be in [1, 99]");
  }
  pending_.reserve(options_.readouts_per_set);
}

void Parser::abandon_pending() {
  if (!pending_.empty()) {
    drop(DropReason::kIncompleteSet);
    stats_.frames_discarded += pending_.size();
    pending_.clear();
  }
}

void Parser::reset() {
  const std::size_t left = buffered();
  if (left >= 2) {
    drop(DropReason::kTruncated);  // a header and part of its frame
  } else if (left == 1) {
    drop(DropReason::kGarbage);  // a lone first header byte
  }
  abandon_pending();
  broken_ = false;
  prev_index_ = -1;
  buf_origin_ += buf_.size();
  buf_.clear();
  start_ = 0;
}

namespace {
bool ender_at(const std::uint8_t* f, std::size_t len) { return f[len - 2] == kEnder[0] && f[len - 1] == kEnder[1]; }
}  // namespace

void Parser::feed(std::span<const std::uint8_t> bytes) {
  stats_.bytes += bytes.size();
  if (bytes.empty()) return;
  append(bytes);
  while (true) {
    skip_to_header();
    if (buffered() < 2) break;  // nothing, or a lone first header byte
    if (!take_frame()) break;   // the frame at start_ is not complete yet
  }
}

void Parser::append(std::span<const std::uint8_t> bytes) {
  // Drop what is parsed before appending; what is left is at most one partial
  // frame, so this costs O(frame) per consumed frame, linear overall.
  if (start_ > 0) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(start_));
    buf_origin_ += start_;
    start_ = 0;
  }
  buf_.insert(buf_.end(), bytes.begin(), bytes.end());
}

void Parser::skip_to_header() {
  const std::uint8_t* base = buf_.data();
  const std::size_t end = buf_.size();
  std::size_t p = start_;
  while (p < end) {
    const void* hit = std::memchr(base + p, kHeader[0], end - p);
    if (hit == nullptr) {
      p = end;
      break;
    }
    p = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - base);
    if (p + 1 >= end || base[p + 1] == kHeader[1]) break;  // a header, or a first byte to keep
    ++p;
  }
  if (p > start_) {
    drop(DropReason::kGarbage, p - start_);
    start_ = p;
  }
}

bool Parser::take_frame() {
  // The decisions below depend only on the frame's bytes, never on how
  // many have arrived beyond what each needs: output is chunking-independent.
  const std::size_t avail = buffered();
  const std::uint8_t* f = buf_.data() + start_;
  if (avail < kDistanceFrameBytes) return false;
  if (ender_at(f, kDistanceFrameBytes)) return accept_frame(kDistanceFrameBytes);
  if (avail < kRawFrameBytes) return false;  // may be a raw frame: wait for its ender position
  if (ender_at(f, kRawFrameBytes)) return accept_frame(kRawFrameBytes);
  // Resume the hunt inside the bad frame: a real header may be there.
  return skip_frame(DropReason::kBadEnder, 2);
}

bool Parser::accept_frame(std::size_t len) {
  if (len == kDistanceFrameBytes) {
    consume_distance(buf_.data() + start_, buf_origin_ + start_ + len);
  } else {
    consume_frame(buf_.data() + start_, buf_origin_ + start_ + len);
  }
  start_ += len;
  return true;
}

bool Parser::skip_frame(DropReason why, std::size_t len) {
  drop(why);
  start_ += len;
  return true;
}

void Parser::consume_distance(const std::uint8_t* frame, std::uint64_t end_byte) {
  DistanceFrame& d = distances_.emplace_back();
  get_u16_array(frame + 2, d.distance);
  d.end_byte = end_byte;
  d.sequence = stats_.frames + stats_.frames_dropped();
  ++stats_.frames;
  ++stats_.distance_frames;
}

void Parser::consume_frame(const std::uint8_t* frame, std::uint64_t end_byte) {
  const std::uint8_t* p = frame + 2;
  const std::uint16_t index_word = get_u16(p);
  const std::uint16_t packed = get_u16(p + 2);
  // Last when above 100, as the public driver reads it; a set of one sends 101.
  const bool last = index_word > kLastFrameFlag;
  std::uint16_t index = static_cast<std::uint16_t>(last ? index_word - kLastFrameFlag : index_word);
  if (last && options_.readouts_per_set == 1 && index == 1) index = 0;
  const std::uint16_t pulses = static_cast<std::uint16_t>((packed % 100) * 10);
  if (index >= options_.readouts_per_set || pulses == 0) {
    // Its set is unknown; the set being assembled cannot complete without it.
    // (With nothing pending, the next frame shows whether a set lost its head.)
    drop(DropReason::kBadField);
    if (!pending_.empty()) {
      abandon_pending();
      broken_ = true;
    }
    return;
  }
  ++stats_.frames;
  ++stats_.raw_frames;
  place_in_set(index, pulses);
  if (broken_) {
    ++stats_.frames_discarded;
  } else {
    keep_raw_frame(p, index, last, packed, end_byte);
  }
  if (last) close_set();
}

void Parser::place_in_set(std::uint16_t index, std::uint16_t pulses) {
  // Set membership: a set starts after a flagged last frame, or where neither
  // the index nor the pulses rise (every set accumulates the same pulse
  // schedule). A corrupted index alone (pulses still rising) is damage inside
  // the set, not a new one, so a set seen only in part counts once.
  const bool new_set = prev_index_ < 0 || (index <= prev_index_ && pulses <= prev_pulses_);
  if (new_set) {
    abandon_pending();  // the previous set lost its tail
    broken_ = false;
    if (index != 0) {  // this one lost its head
      drop(DropReason::kIncompleteSet);
      broken_ = true;
    }
  } else if (!broken_ && index != pending_.size()) {
    abandon_pending();  // a member in the middle is missing
    broken_ = true;
  }
  if (!broken_ && !pending_.empty() && pulses <= pending_.back().pulses) {
    abandon_pending();  // read-outs of one set accumulate: pulses must rise
    broken_ = true;
  }
  prev_index_ = index;
  prev_pulses_ = pulses;
}

void Parser::keep_raw_frame(const std::uint8_t* p, std::uint16_t index, bool last, std::uint16_t packed,
                            std::uint64_t end_byte) {
  RawFrame& r = pending_.emplace_back();
  r.index = index;
  r.last = last;
  r.temperature_decic = packed / 100;
  r.pulses = static_cast<std::uint16_t>((packed % 100) * 10);
  r.end_byte = end_byte;
  get_i16_array(p + 4, r.a);
  get_i16_array(p + 4 + 2 * kPixels, r.b);
  std::uint64_t impossible = 0;
  for (std::size_t i = 0; i < kPixels; ++i) {
    impossible += static_cast<std::uint64_t>(std::abs(r.a[i]) > kMaxRawMagnitude) +
                  static_cast<std::uint64_t>(std::abs(r.b[i]) > kMaxRawMagnitude);
  }
  stats_.impossible_values += impossible;
  if (pending_.size() == options_.readouts_per_set && !last) {
    abandon_pending();  // full but not flagged: the flag is part of the framing
    broken_ = true;
  }
}

void Parser::close_set() {
  if (!broken_) {
    if (pending_.size() == options_.readouts_per_set) {
      sets_.push_back(RawSet{std::move(pending_), stats_.sets + stats_.dropped(DropReason::kIncompleteSet)});
      pending_ = {};
      pending_.reserve(options_.readouts_per_set);
      ++stats_.sets;
    } else {
      abandon_pending();  // flagged before all members came
    }
  }
  broken_ = false;
  prev_index_ = -1;
}

std::optional<RawSet> Parser::next_set() {
  if (sets_taken_ >= sets_.size()) {
    sets_.clear();
    sets_taken_ = 0;
    return std::nullopt;
  }
  return std::move(sets_[sets_taken_++]);
}

std::optional<DistanceFrame> Parser::next_distance() {
  if (distances_taken_ >= distances_.size()) {
    distances_.clear();
    distances_taken_ = 0;
    return std::nullopt;
  }
  return distances_[distances_taken_++];
}

std::size_t Parser::ready() const { return (sets_.size() - sets_taken_) + (distances_.size() - distances_taken_); }

// ---------------------------------------------------------------------------- host commands

std::vector<std::uint8_t> cmd_reset(std::uint8_t pulses_div10) { return {'R', pulses_div10}; }
std::vector<std::uint8_t> cmd_sample() { return {'S'}; }
std::vector<std::uint8_t> cmd_sample_restart() { return {'P'}; }

std::vector<std::uint8_t> cmd_framed(FramedCommand c, std::span<const std::uint8_t> args) {
  if (args.size() + 1 > 255) throw std::invalid_argument("framed command payload too long");
  std::vector<std::uint8_t> out{kCmdStart, static_cast<std::uint8_t>(args.size() + 1), static_cast<std::uint8_t>(c)};
  out.insert(out.end(), args.begin(), args.end());
  out.push_back(kCmdEnd);
  return out;
}

std::vector<std::uint8_t> cmd_framed_reset(std::int16_t pulses) {
  const auto v = static_cast<std::uint16_t>(pulses);
  const std::uint8_t a[2] = {static_cast<std::uint8_t>(v & 0xFF), static_cast<std::uint8_t>(v >> 8)};
  return cmd_framed(FramedCommand::kReset, a);
}

std::vector<std::uint8_t> cmd_laser(bool on) {
  const std::uint8_t a = on ? 1 : 0;
  return cmd_framed(FramedCommand::kLaser, {&a, 1});
}

std::vector<std::uint8_t> cmd_stream_mode(StreamMode m) {
  const std::uint8_t a = m == StreamMode::Raw ? 1 : 0;
  return cmd_framed(FramedCommand::kStreamMode, {&a, 1});
}

void CommandParser::feed(std::span<const std::uint8_t> bytes) {
  buf_.insert(buf_.end(), bytes.begin(), bytes.end());
  std::size_t i = 0;
  while (i < buf_.size()) {
    const std::uint8_t c = buf_[i];
    if (c == 'S' || c == 'P') {
      out_.push_back({c == 'S' ? HostCommand::Kind::Sample : HostCommand::Kind::SampleRestart, 0});
      ++i;
    } else if (c == 'R') {
      if (i + 1 >= buf_.size()) break;
      out_.push_back({HostCommand::Kind::Reset, buf_[i + 1] * 10});
      i += 2;
    } else if (c == kCmdStart) {
      if (i + 1 >= buf_.size()) break;
      const std::size_t len = buf_[i + 1];
      if (i + 2 + len + 1 > buf_.size()) break;
      if (len == 0 || buf_[i + 2 + len] != kCmdEnd) {
        ++garbage_;
        ++i;
        continue;
      }
      const std::uint8_t* pl = buf_.data() + i + 2;
      HostCommand h;
      const auto code = static_cast<FramedCommand>(pl[0]);
      const std::int32_t arg16 = len >= 3 ? static_cast<std::int16_t>(pl[1] | (pl[2] << 8)) : 0;
      const std::int32_t arg8 = len >= 2 ? pl[1] : 0;
      switch (code) {
        case FramedCommand::kReset: h = {HostCommand::Kind::FramedReset, arg16}; break;
        case FramedCommand::kSample: h = {HostCommand::Kind::FramedSample, arg16}; break;
        case FramedCommand::kLaser: h = {HostCommand::Kind::Laser, arg8}; break;
        case FramedCommand::kStreamMode: h = {HostCommand::Kind::StreamMode, arg8}; break;
        default: h = {HostCommand::Kind::Unknown, pl[0]}; break;
      }
      out_.push_back(h);
      i += 2 + len + 1;
    } else {
      ++garbage_;
      ++i;
    }
  }
  buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(i));
}

std::optional<HostCommand> CommandParser::next() {
  if (taken_ >= out_.size()) {
    out_.clear();
    taken_ = 0;
    return std::nullopt;
  }
  return out_[taken_++];
}

}  // namespace tinyline::tiny_laser_driver
