// SPDX-License-Identifier: Apache-2.0
// The parameter table of the recorder node's settings (RecorderOptions),
// described once (<tinyline/common/param_table.hpp>): the recorder declares
// its parameters from it, `tinyline describe` and docs/parameters.md show it.
#pragma once

#include <tinyline/common/param_table.hpp>

#include <tinyline/bag/recorder.hpp>

namespace tinyline::bag {

/// The words of RecorderOptions' chunk compression.
inline constexpr common::Choice<Compression> kCompressions[] = {
    {"none", Compression::None}, {"lz4", Compression::Lz4}, {"zstd", Compression::Zstd}};

/// Bytes per KiB and per MiB: the sizes are set in those, held in bytes.
inline constexpr double kBytesPerKiB = 1024.0;
inline constexpr double kBytesPerMiB = 1024.0 * 1024.0;

template <class S, class V>
requires common::SettingsOf<S, RecorderOptions>
void for_each_param(S& p, V&& v) {
  v(p.path, {"path", "", {}, {}, "output MCAP file (empty: tinyline_<date>_<time>.mcap)"}, common::OutputFile{});
  v(p.topics, {"topics", "", {}, {}, "topics to record (empty: all)"});
  v(p.exclude, {"exclude", "", {}, {}, "topics never recorded"});
  v(p.queue_depth, {"queue_depth", "messages", 1, 1e7, "reliable subscription queue per topic"});
  // Only the writer's settings a recording chooses; the rest (profile, indexes,
  // CRCs, buffer recycling) are what makes the file a ROS 2 bag.
  v(p.writer.writer.compression, {"compression", "", {}, {}, "chunk compression"}, kCompressions);
  v(p.writer.writer.compression_level,
    {"compression_level", "", 0, 19, "lz4 0 (fast) or 1-12; zstd 1-19 (0: library default)"});
  v(p.writer.writer.chunk_size_bytes, {"chunk_size_kb", "KiB", 1, 1 << 20, "uncompressed chunk size", kBytesPerKiB});
  v(p.writer.max_queue_bytes, {"max_queue_mb", "MiB", 1, 1 << 20,
                               "serialized bytes waiting for the disk before messages are refused", kBytesPerMiB});
  v(p.writer.flush_interval_s, {"flush_interval_s", "s", 0.0, 3600.0,
                                "close a chunk after this long without one, so a crash loses little (0: only full "
                                "chunks)"});
}

}  // namespace tinyline::bag
