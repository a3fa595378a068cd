// SPDX-License-Identifier: Apache-2.0
// Stage timestamps for the DDS latency breakdown (bench/dds/dds_breakdown):
// compiled in only where TINYLINE_DDS_PROBES is defined (the benchmark's own
// build of this library); everywhere else a probe is nothing at all.
//
// Each stage keeps the steady-clock time of its first kMaxMarks passes, in
// order. With one message in flight, the k-th mark of every stage in both
// processes belongs to the k-th round trip.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace tinyline::dds::probe {

enum class Stage : int {
  Publish,       ///< a node (or the engine's ping/relay) is about to publish
  SendEnter,     ///< the bridge's tap has the message (local subscribers have it)
  Serialized,    ///< CDR bytes ready
  Written,       ///< dds_writecdr returned
  FromSer,       ///< Cyclone's receive thread builds our sample from the packet
  Taken,         ///< the bridge took the sample off its DDS reader
  Deserialized,  ///< the message object exists
  Delivered,     ///< the local publish returned (queued for the subscribers' executor)
  Arrival,       ///< the subscriber's callback (or the engine's listener) runs
  Count
};
constexpr std::size_t kMaxMarks = std::size_t{1} << 17;

const char* name(Stage s);

#if defined(TINYLINE_DDS_PROBES)
void mark(Stage s);
/// Forgets every mark.
void reset();
/// Every stage's marks so far (steady clock, ns).
std::vector<std::vector<std::int64_t>> marks();
/// Writes marks() as text, one "stage index ns" line each. Throws on I/O errors.
void write(const std::string& path);
/// Reads what write() wrote.
std::vector<std::vector<std::int64_t>> read(const std::string& path);
#define TL_DDS_PROBE(stage) ::tinyline::dds::probe::mark(::tinyline::dds::probe::Stage::stage)
#else
#define TL_DDS_PROBE(stage) ((void)0)
#endif

}  // namespace tinyline::dds::probe
