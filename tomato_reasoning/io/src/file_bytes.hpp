// SPDX-License-Identifier: Apache-2.0
// Whole files in and out, for the image and intrinsics files of an RGB-D
// folder: only a regular file is read (opened non-blocking, so a FIFO is
// refused instead of waited on), and a file is written to "<path>.part" and
// renamed onto its path: common's files helper, its errors as RgbdFileError.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace tinyline::tomato_reasoning::io::detail {

/// The bytes of `path`; throws RgbdFileError naming `what` and the path when
/// it is missing, not a regular file, larger than max_bytes or unreadable.
[[nodiscard]] std::vector<std::uint8_t> read_bytes(const std::string& path, std::string_view what,
                                                   std::uint64_t max_bytes);

/// Writes `bytes` to "<path>.part" and renames it onto `path`; on failure
/// the .part file is removed and `path` keeps what it had.
void write_atomically(const std::string& path, std::string_view what, const void* bytes, std::size_t size);

}  // namespace tinyline::tomato_reasoning::io::detail
