// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/compression.hpp>

#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <limits>

#include <fmt/format.h>

namespace tinyline::bag {

std::string_view mcap_name(Compression c) {
  switch (c) {
    case Compression::None: return "";
    case Compression::Lz4: return "lz4";
    case Compression::Zstd: return "zstd";
  }
  return "";
}

std::string_view to_string(Compression c) { return c == Compression::None ? "none" : mcap_name(c); }

std::optional<Compression> parse_compression(std::string_view s) {
  if (s.empty() || s == "none") return Compression::None;
  if (s == "lz4") return Compression::Lz4;
  if (s == "zstd") return Compression::Zstd;
  return std::nullopt;
}

// ---------------------------------------------------------------------------- Compressor

struct Compressor::Impl {
  LZ4F_cctx* lz4 = nullptr;
  ZSTD_CCtx* zstd = nullptr;
  ~Impl() {
    if (lz4 != nullptr) LZ4F_freeCompressionContext(lz4);
    if (zstd != nullptr) ZSTD_freeCCtx(zstd);
  }
};

Compressor::Compressor(Compression c, int level) : type_(c), level_(level), impl_(std::make_unique<Impl>()) {
  if (c == Compression::Lz4) {
    if (LZ4F_isError(LZ4F_createCompressionContext(&impl_->lz4, LZ4F_VERSION))) impl_->lz4 = nullptr;
  } else if (c == Compression::Zstd) {
    impl_->zstd = ZSTD_createCCtx();
  }
}

Compressor::~Compressor() = default;

Status Compressor::compress(std::span<const std::uint8_t> in, std::vector<std::uint8_t>& buffer,
                            std::span<const std::uint8_t>& result) {
  auto& out = buffer;
  auto reserve = [&](std::size_t n) {
    if (out.size() < n) out.resize(n);
  };
  switch (type_) {
    case Compression::None: result = in; return {};
    case Compression::Lz4: {
      if (impl_->lz4 == nullptr) return {StatusCode::WriteFailed, "lz4: cannot create a compression context"};
      LZ4F_preferences_t prefs{};
      // 256 KiB blocks: lz4's window is 64 KiB, so larger blocks gain almost
      // nothing, and the context's staging buffer stays small.
      prefs.frameInfo.blockSizeID = LZ4F_max256KB;
      prefs.frameInfo.blockMode = LZ4F_blockIndependent;
      prefs.frameInfo.contentSize = in.size();  // lets readers size their buffer exactly
      prefs.compressionLevel = level_;
      reserve(LZ4F_compressFrameBound(in.size(), &prefs));
      // Begin/update/end on a kept context: no allocation per chunk.
      std::size_t n = LZ4F_compressBegin(impl_->lz4, out.data(), out.size(), &prefs);
      std::size_t total = n;
      if (!LZ4F_isError(n)) {
        n = LZ4F_compressUpdate(impl_->lz4, out.data() + total, out.size() - total, in.data(), in.size(), nullptr);
        total += LZ4F_isError(n) ? 0 : n;
      }
      if (!LZ4F_isError(n)) {
        n = LZ4F_compressEnd(impl_->lz4, out.data() + total, out.size() - total, nullptr);
        total += LZ4F_isError(n) ? 0 : n;
      }
      if (LZ4F_isError(n)) {
        return {StatusCode::WriteFailed,
                fmt::format("lz4 compression of {} bytes failed: {}", in.size(), LZ4F_getErrorName(n))};
      }
      result = std::span<const std::uint8_t>(out.data(), total);
      return {};
    }
    case Compression::Zstd: {
      if (impl_->zstd == nullptr) return {StatusCode::WriteFailed, "zstd: cannot create a compression context"};
      reserve(ZSTD_compressBound(in.size()));
      const int level = level_ == 0 ? ZSTD_CLEVEL_DEFAULT : level_;
      const std::size_t n = ZSTD_compressCCtx(impl_->zstd, out.data(), out.size(), in.data(), in.size(), level);
      if (ZSTD_isError(n)) {
        return {StatusCode::WriteFailed,
                fmt::format("zstd compression of {} bytes failed: {}", in.size(), ZSTD_getErrorName(n))};
      }
      result = std::span<const std::uint8_t>(out.data(), n);
      return {};
    }
  }
  return {StatusCode::InvalidArgument, "unknown compression"};
}

// ---------------------------------------------------------------------------- decompress

namespace {

// Contexts are reused per thread: creating one per chunk would cost more
// than decompressing a small chunk.
struct Lz4D {
  LZ4F_dctx* ctx = nullptr;
  Lz4D() {
    if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) ctx = nullptr;
  }
  ~Lz4D() {
    if (ctx != nullptr) LZ4F_freeDecompressionContext(ctx);
  }
};
struct ZstdD {
  ZSTD_DCtx* ctx = ZSTD_createDCtx();
  ~ZstdD() { ZSTD_freeDCtx(ctx); }
};

// Output grows as it is produced: the declared size is trusted in advance only
// up to a multiple of the compressed size (so a few corrupt bytes cannot make
// the reader allocate gigabytes); past that the buffer doubles as output comes.
constexpr std::uint64_t kUpfrontMin = 1ULL << 20;
constexpr std::uint64_t kUpfrontRatio = 8;

// Grows `out` (capacity limit: target + 1, the extra byte detects overflow).
bool grow(std::vector<std::uint8_t>& out, std::uint64_t limit) {
  if (out.size() >= limit) return false;
  const std::uint64_t next = std::min<std::uint64_t>(limit, std::max<std::uint64_t>(out.size() * 2, 1 << 16));
  out.resize(static_cast<std::size_t>(next));
  return true;
}

// Where a streaming decompression stands.
struct Progress {
  std::size_t produced = 0;
  std::size_t consumed = 0;
  bool frame_done = false;
};

// lz4 frame into `out`, growing it up to `limit`; an error names the byte.
Status lz4_stream(std::span<const std::uint8_t> in, std::uint64_t limit, std::vector<std::uint8_t>& out,
                  std::string_view where, Progress& p) {
  thread_local Lz4D d;
  if (d.ctx == nullptr) return {StatusCode::DecompressFailed, fmt::format("{}: no lz4 context", where)};
  LZ4F_resetDecompressionContext(d.ctx);
  while (true) {
    if (p.produced == out.size() && !grow(out, limit)) break;
    std::size_t dst = out.size() - p.produced;
    std::size_t src = in.size() - p.consumed;
    const std::size_t r = LZ4F_decompress(d.ctx, out.data() + p.produced, &dst, in.data() + p.consumed, &src, nullptr);
    if (LZ4F_isError(r)) {
      LZ4F_resetDecompressionContext(d.ctx);
      return {StatusCode::DecompressFailed,
              fmt::format("{}: lz4 data corrupt at compressed byte {}: {}", where, p.consumed, LZ4F_getErrorName(r))};
    }
    p.produced += dst;
    p.consumed += src;
    p.frame_done = r == 0;
    if (p.consumed == in.size() && (p.frame_done || (dst == 0 && src == 0))) break;
    if (dst == 0 && src == 0 && p.produced < out.size()) break;  // no progress possible
  }
  return {};
}

// zstd frame into `out`, growing it up to `limit`; an error names the byte.
Status zstd_stream(std::span<const std::uint8_t> in, std::uint64_t limit, std::vector<std::uint8_t>& out,
                   std::string_view where, Progress& p) {
  thread_local ZstdD d;
  if (d.ctx == nullptr) return {StatusCode::DecompressFailed, fmt::format("{}: no zstd context", where)};
  ZSTD_DCtx_reset(d.ctx, ZSTD_reset_session_only);
  while (true) {
    if (p.produced == out.size() && !grow(out, limit)) break;
    ZSTD_outBuffer ob{out.data(), out.size(), p.produced};
    ZSTD_inBuffer ib{in.data(), in.size(), p.consumed};
    const std::size_t r = ZSTD_decompressStream(d.ctx, &ob, &ib);
    if (ZSTD_isError(r)) {
      ZSTD_DCtx_reset(d.ctx, ZSTD_reset_session_only);
      return {StatusCode::DecompressFailed,
              fmt::format("{}: zstd data corrupt at compressed byte {}: {}", where, p.consumed, ZSTD_getErrorName(r))};
    }
    const bool progress = ob.pos != p.produced || ib.pos != p.consumed;
    p.produced = ob.pos;
    p.consumed = ib.pos;
    p.frame_done = r == 0;
    if (p.consumed == in.size() && p.frame_done) break;
    if (!progress && p.produced < out.size()) break;
  }
  return {};
}

// The stream must end with its frame, use every input byte and give exactly the declared size.
Status check_end(const Progress& p, std::string_view compression, std::size_t in_size, std::uint64_t uncompressed_size,
                 std::string_view where) {
  if (p.produced > uncompressed_size) {
    return {StatusCode::InvalidRecord, fmt::format("{}: {} data decompresses to more than the declared {} bytes", where,
                                                   compression, uncompressed_size)};
  }
  if (!p.frame_done || p.consumed != in_size) {
    return {StatusCode::DecompressFailed,
            fmt::format("{}: {} stream ends early: {} of {} compressed bytes used, {} bytes out", where, compression,
                        p.consumed, in_size, p.produced)};
  }
  if (p.produced != uncompressed_size) {
    return {StatusCode::InvalidRecord, fmt::format("{}: {} data decompresses to {} bytes, the chunk declares {}", where,
                                                   compression, p.produced, uncompressed_size)};
  }
  return {};
}

}  // namespace

Status decompress(std::string_view compression, std::span<const std::uint8_t> in, std::uint64_t uncompressed_size,
                  std::uint64_t max_bytes, std::vector<std::uint8_t>& out, std::string_view where) {
  if (uncompressed_size > max_bytes) {
    return {StatusCode::LimitExceeded, fmt::format("{}: chunk claims {} uncompressed bytes, more than the limit of {}",
                                                   where, uncompressed_size, max_bytes)};
  }
  if (compression.empty()) {
    if (in.size() != uncompressed_size) {
      return {StatusCode::InvalidRecord, fmt::format("{}: uncompressed chunk holds {} bytes but declares {}", where,
                                                     in.size(), uncompressed_size)};
    }
    out.assign(in.begin(), in.end());
    return {};
  }
  const bool lz4 = compression == "lz4";
  if (!lz4 && compression != "zstd") {
    return {StatusCode::Unsupported,
            fmt::format("{}: unsupported chunk compression '{}' (this reader knows lz4 and zstd)", where, compression)};
  }
  const std::uint64_t limit = uncompressed_size + 1;
  out.resize(static_cast<std::size_t>(
      std::min(limit, std::max<std::uint64_t>(kUpfrontMin, kUpfrontRatio * static_cast<std::uint64_t>(in.size())))));
  Progress p;
  if (Status s = lz4 ? lz4_stream(in, limit, out, where, p) : zstd_stream(in, limit, out, where, p); !s.ok()) return s;
  if (Status s = check_end(p, compression, in.size(), uncompressed_size, where); !s.ok()) return s;
  out.resize(p.produced);
  return {};
}

}  // namespace tinyline::bag
