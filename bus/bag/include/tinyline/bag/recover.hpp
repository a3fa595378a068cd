// SPDX-License-Identifier: Apache-2.0
// Recovery: rewrites what is readable in a damaged or unfinished MCAP file
// (a recorder killed mid-file, a cut copy, flipped bytes) as a complete file
// with a summary. Every record up to the point where the file stops making
// sense is kept; a chunk that fails its CRC or decompression is skipped and
// reported; messages keep their channels, times and sequence numbers.
//
// When the file still ends with an intact summary (under its CRC), its
// schemas and channels are trusted over the data section's copies (a
// disagreement is reported and the summary's used), and every chunk its
// indexes list is read even if a damaged record threw the linear pass off.
// Strings that cannot be right (not UTF-8, control characters, a topic that
// is no ROS name in a cdr channel, an encoding that is no name) are never
// copied into the new file, whose fresh CRCs would vouch for them: such a
// record is refused and reported, with the messages that depend on it.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <tinyline/bag/io.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/writer.hpp>

namespace tinyline::bag {

struct RecoverOptions {
  /// How the new file is written (profile and library are taken from the input's header).
  WriterOptions writer;
  /// Check chunk CRCs of the input (a chunk that fails is skipped).
  bool validate_crcs = true;
  std::uint64_t max_record_bytes = std::uint64_t{1} << 32;
};

struct RecoverReport {
  std::uint64_t messages = 0;
  std::uint64_t schemas = 0;
  std::uint64_t channels = 0;
  std::uint64_t attachments = 0;
  std::uint64_t metadata = 0;
  std::uint64_t messages_skipped = 0;   ///< on a refused channel, or outside the summary's time span
  std::uint64_t chunks = 0;             ///< chunks of the input read whole
  std::uint64_t chunks_from_index = 0;  ///< of those, found through the summary's chunk indexes
  std::uint64_t chunks_skipped = 0;     ///< chunks dropped for a CRC, decompression or record error
  std::uint64_t input_bytes = 0;
  std::uint64_t bytes_used = 0;       ///< input bytes up to the last readable record
  bool input_complete = false;        ///< the input already had a data end record
  std::vector<ReadProblem> problems;  ///< everything stepped over or refused, with byte offsets
};

/// Reads `in` and writes the recovered file to `out` (which the caller keeps and closes).
Status recover(Readable& in, Writable& out, const RecoverOptions& options, RecoverReport& report);
Status recover(const std::string& in_path, const std::string& out_path, const RecoverOptions& options,
               RecoverReport& report);

}  // namespace tinyline::bag
