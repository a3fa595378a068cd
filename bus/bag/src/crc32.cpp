// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/crc32.hpp>

#include <array>
#include <cstring>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define TL_CRC_PCLMUL 1
#endif

namespace tinyline::bag {

namespace {

// The portable path, slicing-by-16: sixteen 256-entry tables let the loop fold 16 bytes per
// step with independent lookups (about 4x the byte-wise loop).
constexpr std::array<std::array<std::uint32_t, 256>, 16> make_tables() {
  std::array<std::array<std::uint32_t, 256>, 16> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1U) ? (0xEDB88320U ^ (c >> 1)) : (c >> 1);
    t[0][i] = c;
  }
  for (std::size_t s = 1; s < 16; ++s) {
    for (std::uint32_t i = 0; i < 256; ++i) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFFU];
  }
  return t;
}

constexpr auto kTables = make_tables();

inline std::uint32_t load32(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

std::uint32_t crc_tables(std::uint32_t c, const std::uint8_t* p, std::size_t n) {
  const auto& T = kTables;
  while (n >= 16) {
    const std::uint32_t a = load32(p) ^ c;
    const std::uint32_t b = load32(p + 4);
    const std::uint32_t d = load32(p + 8);
    const std::uint32_t e = load32(p + 12);
    c = T[15][a & 0xFF] ^ T[14][(a >> 8) & 0xFF] ^ T[13][(a >> 16) & 0xFF] ^ T[12][a >> 24] ^ T[11][b & 0xFF] ^
        T[10][(b >> 8) & 0xFF] ^ T[9][(b >> 16) & 0xFF] ^ T[8][b >> 24] ^ T[7][d & 0xFF] ^ T[6][(d >> 8) & 0xFF] ^
        T[5][(d >> 16) & 0xFF] ^ T[4][d >> 24] ^ T[3][e & 0xFF] ^ T[2][(e >> 8) & 0xFF] ^ T[1][(e >> 16) & 0xFF] ^
        T[0][e >> 24];
    p += 16;
    n -= 16;
  }
  while (n-- > 0) c = T[0][(c ^ *p++) & 0xFF] ^ (c >> 8);
  return c;
}

#ifdef TL_CRC_PCLMUL
// Carry-less multiplication folding (Gopal et al., "Fast CRC Computation for
// Generic Polynomials Using PCLMULQDQ Instruction", Intel 2009), with the
// constants of the bit-reflected CRC-32 polynomial: folds 64 bytes per step
// in four independent lanes, then reduces 128 -> 64 -> 32 bits (Barrett).
// `c` is the running (inverted) register; n is a multiple of 16, >= 64.
__attribute__((target("pclmul,sse4.1"))) inline __m128i fold16(__m128i x, __m128i k) {
  return _mm_xor_si128(_mm_clmulepi64_si128(x, k, 0x00), _mm_clmulepi64_si128(x, k, 0x11));
}

__attribute__((target("pclmul,sse4.1"))) inline __m128i load16(const std::uint8_t* q) {
  return _mm_loadu_si128(reinterpret_cast<const __m128i*>(q));
}

__attribute__((target("pclmul,sse4.1"))) std::uint32_t crc_pclmul(std::uint32_t c, const std::uint8_t* p,
                                                                  std::size_t n) {
  const __m128i k1k2 = _mm_set_epi64x(0x1c6e41596LL, 0x154442bd4LL);     // x^(4*128+32), x^(4*128-32) mod P
  const __m128i k3k4 = _mm_set_epi64x(0x0ccaa009eLL, 0x1751997d0LL);     // x^(128+32), x^(128-32) mod P
  const __m128i k5 = _mm_set_epi64x(0, 0x163cd6124LL);                   // x^64 mod P
  const __m128i poly_mu = _mm_set_epi64x(0x1f7011641LL, 0x1db710641LL);  // mu, P (bit-reflected)
  const __m128i mask32 = _mm_set_epi32(0, 0, 0, -1);
  __m128i x0 = _mm_xor_si128(load16(p), _mm_cvtsi32_si128(static_cast<int>(c)));
  __m128i x1 = load16(p + 16), x2 = load16(p + 32), x3 = load16(p + 48);
  p += 64;
  n -= 64;
  while (n >= 64) {
    x0 = _mm_xor_si128(fold16(x0, k1k2), load16(p));
    x1 = _mm_xor_si128(fold16(x1, k1k2), load16(p + 16));
    x2 = _mm_xor_si128(fold16(x2, k1k2), load16(p + 32));
    x3 = _mm_xor_si128(fold16(x3, k1k2), load16(p + 48));
    p += 64;
    n -= 64;
  }
  x0 = _mm_xor_si128(fold16(x0, k3k4), x1);
  x0 = _mm_xor_si128(fold16(x0, k3k4), x2);
  x0 = _mm_xor_si128(fold16(x0, k3k4), x3);
  while (n >= 16) {
    x0 = _mm_xor_si128(fold16(x0, k3k4), load16(p));
    p += 16;
    n -= 16;
  }
  // 128 -> 64 bits (appending 32 zero bits), then 64 -> 32.
  x0 = _mm_xor_si128(_mm_clmulepi64_si128(k3k4, x0, 0x01), _mm_srli_si128(x0, 8));
  x0 = _mm_xor_si128(_mm_clmulepi64_si128(_mm_and_si128(x0, mask32), k5, 0x00), _mm_srli_si128(x0, 4));
  // Barrett reduction.
  __m128i t = _mm_clmulepi64_si128(_mm_and_si128(x0, mask32), poly_mu, 0x10);
  t = _mm_clmulepi64_si128(_mm_and_si128(t, mask32), poly_mu, 0x00);
  return static_cast<std::uint32_t>(_mm_extract_epi32(_mm_xor_si128(t, x0), 1));
}

const bool kHavePclmul = __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
#endif

}  // namespace

std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t crc) {
  std::uint32_t c = ~crc;
  const std::uint8_t* p = bytes.data();
  std::size_t n = bytes.size();
#ifdef TL_CRC_PCLMUL
  if (kHavePclmul && n >= 64) {
    const std::size_t bulk = n & ~std::size_t{15};
    c = crc_pclmul(c, p, bulk);
    p += bulk;
    n -= bulk;
  }
#endif
  return ~crc_tables(c, p, n);
}

namespace {
// CRC combination in GF(2): appending n zero bits to a CRC is a linear map,
// a 32x32 bit matrix; squaring it doubles n, so len2 bytes cost O(log len2).
std::uint32_t gf2_times(const std::uint32_t* mat, std::uint32_t vec) {
  std::uint32_t sum = 0;
  for (; vec != 0; vec >>= 1, ++mat) {
    if (vec & 1U) sum ^= *mat;
  }
  return sum;
}
void gf2_square(std::uint32_t* square, const std::uint32_t* mat) {
  for (int n = 0; n < 32; ++n) square[n] = gf2_times(mat, mat[n]);
}
}  // namespace

std::uint32_t crc32_combine(std::uint32_t crc1, std::uint32_t crc2, std::uint64_t len2) {
  if (len2 == 0) return crc1;
  std::uint32_t even[32], odd[32];
  odd[0] = 0xEDB88320U;  // one zero bit
  std::uint32_t row = 1;
  for (int n = 1; n < 32; ++n, row <<= 1) odd[n] = row;
  gf2_square(even, odd);  // two zero bits
  gf2_square(odd, even);  // four
  do {                    // apply len2 bytes of zeros to crc1
    gf2_square(even, odd);
    if (len2 & 1U) crc1 = gf2_times(even, crc1);
    len2 >>= 1;
    if (len2 == 0) break;
    gf2_square(odd, even);
    if (len2 & 1U) crc1 = gf2_times(odd, crc1);
    len2 >>= 1;
  } while (len2 != 0);
  return crc1 ^ crc2;
}

std::uint32_t crc32_portable(std::span<const std::uint8_t> bytes, std::uint32_t crc) {
  return ~crc_tables(~crc, bytes.data(), bytes.size());
}

}  // namespace tinyline::bag
