// SPDX-License-Identifier: Apache-2.0
#include "probe.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <fstream>
#include <memory>
#include <stdexcept>

#include <tinyline/common/files.hpp>

namespace tinyline::dds::probe {

const char* name(Stage s) {
  switch (s) {
    case Stage::Publish: return "publish";
    case Stage::SendEnter: return "send_enter";
    case Stage::Serialized: return "serialized";
    case Stage::Written: return "written";
    case Stage::FromSer: return "from_ser";
    case Stage::Taken: return "taken";
    case Stage::Deserialized: return "deserialized";
    case Stage::Delivered: return "delivered";
    case Stage::Arrival: return "arrival";
    case Stage::Count: break;
  }
  return "?";
}

#if defined(TINYLINE_DDS_PROBES)
namespace {
constexpr auto kStages = static_cast<std::size_t>(Stage::Count);
struct Marks {
  std::array<std::atomic<std::size_t>, kStages> next{};
  std::array<std::unique_ptr<std::int64_t[]>, kStages> at;
  Marks() {
    for (auto& a : at) a = std::make_unique<std::int64_t[]>(kMaxMarks);
  }
};
Marks& g() {
  static Marks m;
  return m;
}
}  // namespace

void mark(Stage s) {
  const auto ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
  auto& m = g();
  const auto i = static_cast<std::size_t>(s);
  const std::size_t k = m.next[i].fetch_add(1, std::memory_order_relaxed);
  if (k < kMaxMarks) m.at[i][k] = ns;
}

void reset() {
  for (auto& n : g().next) n.store(0);
}

std::vector<std::vector<std::int64_t>> marks() {
  auto& m = g();
  std::vector<std::vector<std::int64_t>> out(kStages);
  for (std::size_t i = 0; i < kStages; ++i) {
    const std::size_t n = std::min(m.next[i].load(), kMaxMarks);
    out[i].assign(m.at[i].get(), m.at[i].get() + n);
  }
  return out;
}

void write(const std::string& path) {
  files::AtomicStream f(path, files::named("probe marks"));
  const auto all = marks();
  for (std::size_t i = 0; i < all.size(); ++i)
    for (std::size_t k = 0; k < all[i].size(); ++k) f << i << ' ' << k << ' ' << all[i][k] << '\n';
  f.commit();
}

std::vector<std::vector<std::int64_t>> read(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot read probe marks from " + path);
  std::vector<std::vector<std::int64_t>> out(kStages);
  std::size_t i = 0, k = 0;
  std::int64_t ns = 0;
  while (f >> i >> k >> ns) {
    if (i >= kStages || k != out[i].size()) throw std::runtime_error("malformed probe marks in " + path);
    out[i].push_back(ns);
  }
  return out;
}
#endif

}  // namespace tinyline::dds::probe
