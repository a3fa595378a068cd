#include <tiny_laser_driver/protocol.hpp>

#include <algorithm>
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

void get_i16_array(const std::uint8_t* p, std::array<std::int16_t, kPixels>& v) {
  for (std::size_t i = 0; i < kPixels; ++i) v[i] = static_cast<std::int16_t>(get_u16(p + 2 * i));
}

}  // namespace

std::string_view to_string(DropReason r) {
  switch (r) {
    case DropReason::kGarbage: return "garbage_bytes";
    case DropReason::kBadEnder: return "bad_ender";
    case DropReason::kIncompleteSet: return "incomplete_set";
    case DropReason::kBadField: return "bad_field";
    case DropReason::kCount: break;
  }
  return "?";
}

void encode_raw_frame(const RawFrame& f, std::vector<std::uint8_t>& out) {
  if (f.pulses % 10 != 0 || f.pulses / 10 > 99) {
    throw std::invalid_argument("raw frame pulses must be a multiple of 10 below 1000");
  }
  if (f.temperature_decic > 655) throw std::invalid_argument("raw frame temperature must be below 65.5 degC");
  out.reserve(out.size() + kRawFrameBytes);
  out.insert(out.end(), std::begin(kHeader), std::end(kHeader));
  put_u16(out, static_cast<std::uint16_t>(f.index + (f.last ? kLastFrameFlag : 0)));
  put_u16(out, static_cast<std::uint16_t>(f.temperature_decic * 100 + f.pulses / 10));
  put_i16_array(out, f.a);
  put_i16_array(out, f.b);
  out.insert(out.end(), std::begin(kEnder), std::end(kEnder));
}

void encode_distance_frame(const DistanceFrame& f, std::vector<std::uint8_t>& out) {
  out.reserve(out.size() + kDistanceFrameBytes);
  out.insert(out.end(), std::begin(kHeader), std::end(kHeader));
  put_i16_array(out, f.distance);
  out.insert(out.end(), std::begin(kEnder), std::end(kEnder));
}

// ---------------------------------------------------------------------------- Parser

Parser::Parser(Options options) : options_(options) {
  if (options_.readouts_per_set == 0 || options_.readouts_per_set >= kLastFrameFlag) {
    throw std::invalid_argument("readouts_per_set must be in [1, 99]");
  }
}

void Parser::reset() {
  if (!pending_.empty()) drop(DropReason::kIncompleteSet);
  pending_.clear();
  orphan_ = false;
  buf_.clear();
  start_ = 0;
}

void Parser::feed(std::span<const std::uint8_t> bytes) {
  stats_.bytes += bytes.size();
  buf_.insert(buf_.end(), bytes.begin(), bytes.end());
  const std::size_t frame_len = options_.mode == StreamMode::Raw ? kRawFrameBytes : kDistanceFrameBytes;
  while (true) {
    // Hunt for the two-byte header.
    std::size_t p = start_;
    while (p + 1 < buf_.size() && !(buf_[p] == kHeader[0] && buf_[p + 1] == kHeader[1])) ++p;
    if (p + 1 >= buf_.size()) {
      // No header yet; keep a trailing first header byte, everything else is garbage.
      const std::size_t keep = (!buf_.empty() && buf_.back() == kHeader[0] && p < buf_.size()) ? 1 : 0;
      const std::size_t skip = buf_.size() - start_ - keep;
      drop(DropReason::kGarbage, skip);
      start_ += skip;
      break;
    }
    drop(DropReason::kGarbage, p - start_);
    start_ = p;
    if (buf_.size() - start_ < frame_len) break;  // wait for the rest of the frame
    const std::uint8_t* f = buf_.data() + start_;
    if (f[frame_len - 2] == kEnder[0] && f[frame_len - 1] == kEnder[1]) {
      consume_frame({f, frame_len});
      start_ += frame_len;
    } else {
      drop(DropReason::kBadEnder);
      start_ += 2;  // resume the hunt inside the bad frame: a real header may be there
    }
  }
  // Compact occasionally so the buffer stays small and parsing stays linear.
  if (start_ > 0 && (start_ >= buf_.size() || start_ > 65536)) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(start_));
    start_ = 0;
  }
}

void Parser::consume_frame(std::span<const std::uint8_t> frame) {
  const std::uint8_t* p = frame.data() + 2;
  if (options_.mode == StreamMode::Distance) {
    DistanceFrame d;
    get_i16_array(p, d.distance);
    distances_.push_back(d);
    ++stats_.frames;
    return;
  }
  RawFrame r;
  const std::uint16_t index_word = get_u16(p);
  const std::uint16_t packed = get_u16(p + 2);
  r.last = index_word >= kLastFrameFlag;
  r.index = static_cast<std::uint16_t>(r.last ? index_word - kLastFrameFlag : index_word);
  r.temperature_decic = packed / 100;
  r.pulses = static_cast<std::uint16_t>((packed % 100) * 10);
  if (r.index >= options_.readouts_per_set || r.pulses == 0) {
    drop(DropReason::kBadField);
    if (!pending_.empty()) {
      drop(DropReason::kIncompleteSet);
      orphan_ = !r.last;  // the rest of this set is already counted
    }
    pending_.clear();
    return;
  }
  get_i16_array(p + 4, r.a);
  get_i16_array(p + 4 + 2 * kPixels, r.b);
  ++stats_.frames;
  if (r.index == 0) orphan_ = false;
  if (r.index != pending_.size()) {
    // A member is missing: abandon the set being assembled. A frame that is
    // not a set's first cannot start one either; its set is counted once.
    if (!pending_.empty()) drop(DropReason::kIncompleteSet);
    pending_.clear();
    if (r.index != 0) {
      if (!orphan_) drop(DropReason::kIncompleteSet);
      orphan_ = !r.last;
      return;
    }
  }
  const bool last = r.last;
  pending_.push_back(r);
  if (last || pending_.size() == options_.readouts_per_set) {
    if (last && pending_.size() == options_.readouts_per_set) {
      sets_.push_back(RawSet{std::move(pending_)});
      ++stats_.sets;
    } else {
      drop(DropReason::kIncompleteSet);
    }
    pending_.clear();
  }
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
