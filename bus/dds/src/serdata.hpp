// SPDX-License-Identifier: Apache-2.0
// A Cyclone DDS sertype whose samples are our encapsulated CDR bytes, as
// rmw_cyclonedds does it: no IDL, no generated DDS types, every message type
// works, and the bytes on the wire are exactly the messages' own CDR.
#pragma once

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <tinyline/msg/type_support.hpp>

namespace tinyline::dds::detail {

struct Sertype : ddsi_sertype {
  const msg::TypeSupport* type = nullptr;  ///< may be null: a type tinyline does not know (raw tools)
  std::size_t max_sample_bytes = 0;
};

struct Serdata : ddsi_serdata {
  std::vector<std::uint8_t> bytes;  ///< encapsulated CDR, zero-padded to a multiple of 4
  /// A sample that came through shared memory has no `bytes`: they stay in
  /// its iceoryx chunk (`iox_chunk`, held until the last reference goes).
  /// True when iceoryx said that chunks were lost before this one arrived
  /// (its subscriber queue overflowed: a reader too slow for the writer).
  bool lost_before = false;
  /// The writer a chunk of ours (`iox_chunk` without `iox_subscriber`) was
  /// loaned from while it is not yet published: a sample freed before its
  /// write handed the chunk to iceoryx gives the chunk back to that writer.
  dds_entity_t loaned_from = 0;
};

/// A new sertype named `dds_type_name`; the caller hands it to
/// dds_create_topic_sertype, which owns it from then on.
ddsi_sertype* make_sertype(const std::string& dds_type_name, const msg::TypeSupport* type,
                           std::size_t max_sample_bytes);

/// Wraps serialized bytes (moved in, padded here) as a sample of `type`;
/// refcount 1, for dds_writecdr (which takes that reference).
ddsi_serdata* make_serdata(const ddsi_sertype* type, std::vector<std::uint8_t>&& encapsulated_cdr);

/// Wraps serialized bytes as make_serdata() does and, when `writer` can use
/// shared memory (Cyclone's iceoryx path), also copies them into a chunk
/// loaned from it, which dds_writecdr then publishes to the readers on this
/// machine (the bytes stay for readers over the network). Returns null, with
/// the reason in `error`, when no chunk could be had: those readers would
/// not get the sample.
ddsi_serdata* make_serdata_for(std::int32_t writer, bool shared_memory, const ddsi_sertype* type,
                               std::vector<std::uint8_t>&& encapsulated_cdr, std::string& error);

/// dds_writecdr(writer, d), taking the reference to `d` in every case:
/// Cyclone takes it only once it has the writer locked, so a write refused
/// before that (a deleted or wrong handle) drops it here, and a loaned chunk
/// that was not published goes back to its writer (sd_free).
dds_return_t write_serdata(dds_entity_t writer, ddsi_serdata* d);

/// The bytes of a sample of one of our sertypes (in its shared-memory chunk
/// if it came through one: no copy).
std::span<const std::uint8_t> serdata_bytes(const ddsi_serdata* d);

/// Whether iceoryx reported lost chunks just before this sample came.
bool serdata_lost_before(const ddsi_serdata* d);

/// Thread-sanitizer hand-over marks. Cyclone is not instrumented, so TSan
/// cannot see that its reference counting orders our writes of a sample's
/// bytes before another thread reads or frees them. `handing_over` goes
/// before a reference leaves our code (dds_writecdr, ddsi_serdata_unref),
/// `taking_over` where a thread starts using a sample Cyclone gave it.
/// Both compile to nothing without TSan.
void handing_over(const ddsi_serdata* d);
void taking_over(const ddsi_serdata* d);

}  // namespace tinyline::dds::detail
