#include <tinyline/bag/crc32.hpp>

#include <array>
#include <cstring>

namespace tinyline::bag {

namespace {

// Slicing-by-16: sixteen 256-entry tables let the loop fold 16 bytes per
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

}  // namespace

std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t crc) {
  const auto& T = kTables;
  std::uint32_t c = ~crc;
  const std::uint8_t* p = bytes.data();
  std::size_t n = bytes.size();
  while (n >= 16) {
    const std::uint32_t a = load32(p) ^ c;
    const std::uint32_t b = load32(p + 4);
    const std::uint32_t d = load32(p + 8);
    const std::uint32_t e = load32(p + 12);
    c = T[15][a & 0xFF] ^ T[14][(a >> 8) & 0xFF] ^ T[13][(a >> 16) & 0xFF] ^ T[12][a >> 24] ^
        T[11][b & 0xFF] ^ T[10][(b >> 8) & 0xFF] ^ T[9][(b >> 16) & 0xFF] ^ T[8][b >> 24] ^
        T[7][d & 0xFF] ^ T[6][(d >> 8) & 0xFF] ^ T[5][(d >> 16) & 0xFF] ^ T[4][d >> 24] ^
        T[3][e & 0xFF] ^ T[2][(e >> 8) & 0xFF] ^ T[1][(e >> 16) & 0xFF] ^ T[0][e >> 24];
    p += 16;
    n -= 16;
  }
  while (n-- > 0) c = T[0][(c ^ *p++) & 0xFF] ^ (c >> 8);
  return ~c;
}

}  // namespace tinyline::bag
