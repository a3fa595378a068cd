// SPDX-License-Identifier: Apache-2.0
// CRC-32 (ISO-HDLC, polynomial 0xEDB88320, the zlib crc32) that MCAP uses for
// chunks, the data section, the summary and attachments.
#pragma once

#include <cstdint>
#include <span>

namespace tinyline::bag {

/// Continues a running CRC: crc32(b, crc32(a)) == crc32(a + b); start from 0.
/// Uses carry-less multiplication (PCLMULQDQ) where the CPU has it.
std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t crc = 0);

/// The CRC of A followed by B from crc32(A), crc32(B) and B's length, without
/// reading B again (the writer folds a stored chunk's CRC into the data CRC).
std::uint32_t crc32_combine(std::uint32_t crc_a, std::uint32_t crc_b, std::uint64_t length_b);

/// The table-driven path only (the reference the fast path is tested against).
std::uint32_t crc32_portable(std::span<const std::uint8_t> bytes, std::uint32_t crc = 0);

}  // namespace tinyline::bag
