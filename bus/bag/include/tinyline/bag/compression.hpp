// SPDX-License-Identifier: Apache-2.0
// Chunk compression: lz4 (the LZ4 frame format, as MCAP requires) and zstd,
// both from the system libraries.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/bag/status.hpp>

namespace tinyline::bag {

enum class Compression { None, Lz4, Zstd };

/// The name MCAP stores: "", "lz4", "zstd".
std::string_view mcap_name(Compression c);
/// For humans: "none", "lz4", "zstd".
std::string_view to_string(Compression c);
/// Accepts "none"/"" , "lz4", "zstd"; nothing for anything else.
std::optional<Compression> parse_compression(std::string_view s);

/// A reusable compressor (keeps its contexts between chunks).
class Compressor {
 public:
  /// `level`: lz4: 0 fast (>0 selects the high-compression mode); zstd: 1..19,
  /// 0 means the library default.
  explicit Compressor(Compression c, int level = 0);
  ~Compressor();
  Compressor(const Compressor&) = delete;
  Compressor& operator=(const Compressor&) = delete;

  Compression type() const { return type_; }
  /// Compresses `in` into `buffer` (grown as needed, never shrunk, so a
  /// reused buffer costs no zero-filling) and points `out` at the result.
  Status compress(std::span<const std::uint8_t> in, std::vector<std::uint8_t>& buffer,
                  std::span<const std::uint8_t>& out);

 private:
  struct Impl;
  Compression type_;
  int level_;
  std::unique_ptr<Impl> impl_;
};

/// Decompresses a chunk's records. `compression` is the MCAP name. The output
/// must come out at exactly `uncompressed_size` bytes; output is allocated as
/// it is produced, so a lying size field cannot force a huge allocation, and
/// more than `max_bytes` is refused (LimitExceeded). `where` prefixes errors.
Status decompress(std::string_view compression, std::span<const std::uint8_t> in, std::uint64_t uncompressed_size,
                  std::uint64_t max_bytes, std::vector<std::uint8_t>& out, std::string_view where);

}  // namespace tinyline::bag
