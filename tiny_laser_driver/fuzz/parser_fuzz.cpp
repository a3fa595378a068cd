// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: arbitrary bytes through the streaming parser (both kinds of frame)
// and the host-command parser. Properties beyond "no crash, no sanitizer
// report":
//  - the output and every counter are the same whatever the chunking;
//  - every byte fed is accounted for (frames, drops, garbage, buffer);
//  - every set that comes out is whole: n frames, indices 0..n-1, only the
//    last flagged, pulses rising; every well-formed frame is in a set or
//    counted as discarded;
//  - a set re-encoded and parsed again is the same set.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include <tiny_laser_driver/protocol.hpp>

namespace tl = tinyline::tiny_laser_driver;

namespace {

[[noreturn]] void violated(const char* what) {
  std::fprintf(stderr, "property violated: %s\n", what);
  std::abort();
}
void check(bool ok, const char* what) {
  if (!ok) violated(what);
}

struct Out {
  std::vector<tl::RawSet> sets;
  std::vector<tl::DistanceFrame> distances;
};

Out drain(tl::Parser& p) {
  Out o;
  while (auto s = p.next_set()) o.sets.push_back(std::move(*s));
  while (auto d = p.next_distance()) o.distances.push_back(*d);
  return o;
}

bool same_frame(const tl::RawFrame& x, const tl::RawFrame& y) {
  return x.index == y.index && x.last == y.last && x.temperature_decic == y.temperature_decic && x.pulses == y.pulses &&
         x.a == y.a && x.b == y.b && x.end_byte == y.end_byte;
}

bool same(const Out& x, const Out& y) {
  if (x.sets.size() != y.sets.size() || x.distances.size() != y.distances.size()) return false;
  for (std::size_t i = 0; i < x.sets.size(); ++i) {
    if (x.sets[i].frames.size() != y.sets[i].frames.size()) return false;
    for (std::size_t j = 0; j < x.sets[i].frames.size(); ++j) {
      if (!same_frame(x.sets[i].frames[j], y.sets[i].frames[j])) return false;
    }
  }
  for (std::size_t i = 0; i < x.distances.size(); ++i) {
    if (x.distances[i].distance != y.distances[i].distance || x.distances[i].end_byte != y.distances[i].end_byte) {
      return false;
    }
  }
  return true;
}

bool same_stats(const tl::ParserStats& a, const tl::ParserStats& b) {
  return a.drops == b.drops && a.frames == b.frames && a.frames_discarded == b.frames_discarded && a.sets == b.sets &&
         a.bytes == b.bytes && a.impossible_values == b.impossible_values;
}

void check_accounting(const tl::Parser& p) {
  const auto& s = p.stats();
  const std::uint64_t accounted = (s.raw_frames + s.dropped(tl::DropReason::kBadField)) * tl::kRawFrameBytes +
                                  s.distance_frames * tl::kDistanceFrameBytes +
                                  s.dropped(tl::DropReason::kBadEnder) * 2 + s.dropped(tl::DropReason::kGarbage) +
                                  p.buffered();
  check(accounted == s.bytes, "every byte is accounted for");
  check(s.raw_frames == s.sets * p.options().readouts_per_set + s.frames_discarded + p.pending_frames(),
        "every raw frame is in a set, discarded, or pending");
  check(s.frames == s.raw_frames + s.distance_frames, "every frame is of one kind");
}

void check_sets(const Out& o, std::size_t n) {
  for (const auto& set : o.sets) {
    check(set.frames.size() == n, "a set has all its frames");
    for (std::size_t i = 0; i < n; ++i) {
      const auto& f = set.frames[i];
      check(f.index == i, "frames in index order");
      check(f.last == (i + 1 == n), "only the last frame flagged");
      check(f.pulses > 0 && f.pulses % 10 == 0, "pulses a positive multiple of 10");
      if (i > 0) check(f.pulses > set.frames[i - 1].pulses, "pulses rise within a set");
      if (i > 0) check(f.end_byte > set.frames[i - 1].end_byte, "frames in stream order");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  // Byte 0: set size; byte 1: chunking seed; the rest is the stream (both kinds of frame).
  const std::size_t n = 1 + (data[0] >> 1) % 6;
  std::uint32_t rng = data[1] * 2654435761u + 1;
  const std::span<const std::uint8_t> stream(data + 2, size - 2);
  const tl::Parser::Options opt{n};

  tl::Parser whole(opt);
  whole.feed(stream);
  const Out expected = drain(whole);
  check_accounting(whole);
  check_sets(expected, n);

  tl::Parser chunked(opt);
  std::size_t at = 0;
  while (at < stream.size()) {
    rng = rng * 1664525u + 1013904223u;
    const std::size_t len = std::min<std::size_t>(stream.size() - at, (rng >> 16) % 1500);
    chunked.feed(stream.subspan(at, len));
    at += len;
  }
  check(same(drain(chunked), expected), "output independent of chunking");
  check(same_stats(chunked.stats(), whole.stats()), "counters independent of chunking");

  // Re-encode what came out; it must parse back to the same items.
  std::vector<std::uint8_t> again;
  for (const auto& set : expected.sets) {
    for (const auto& f : set.frames) tl::encode_raw_frame(f, again);
  }
  for (const auto& d : expected.distances) tl::encode_distance_frame(d, again);
  tl::Parser round(opt);
  round.feed(again);
  const Out back = drain(round);
  check(back.sets.size() == expected.sets.size() && back.distances.size() == expected.distances.size(),
        "re-encoded items parse back");
  for (std::size_t i = 0; i < back.sets.size(); ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const auto& x = back.sets[i].frames[j];
      const auto& y = expected.sets[i].frames[j];
      check(x.a == y.a && x.b == y.b && x.pulses == y.pulses && x.temperature_decic == y.temperature_decic,
            "re-encoded frame parses to the same values");
    }
  }
  for (std::size_t i = 0; i < back.distances.size(); ++i) {
    check(back.distances[i].distance == expected.distances[i].distance, "re-encoded distance frame");
  }

  // A disconnect mid-stream, then the stream again: nothing partial comes out.
  whole.reset();
  check(whole.buffered() == 0 && whole.pending_frames() == 0, "reset forgets partial data");
  whole.feed(stream);
  check_sets(drain(whole), n);

  tl::CommandParser cp;
  cp.feed(stream);
  while (auto c = cp.next()) {
    check(c->kind >= tl::HostCommand::Kind::Reset && c->kind <= tl::HostCommand::Kind::Unknown, "command kind");
  }
  return 0;
}
