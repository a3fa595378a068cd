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
};

/// A new sertype named `dds_type_name`; the caller hands it to
/// dds_create_topic_sertype, which owns it from then on.
ddsi_sertype* make_sertype(const std::string& dds_type_name, const msg::TypeSupport* type,
                           std::size_t max_sample_bytes);

/// Wraps serialized bytes (moved in, padded here) as a sample of `type`;
/// refcount 1, for dds_writecdr (which takes that reference).
ddsi_serdata* make_serdata(const ddsi_sertype* type, std::vector<std::uint8_t>&& encapsulated_cdr);

/// The bytes of a sample of one of our sertypes.
std::span<const std::uint8_t> serdata_bytes(const ddsi_serdata* d);

/// Thread-sanitizer hand-over marks. Cyclone is not instrumented, so TSan
/// cannot see that its reference counting orders our writes of a sample's
/// bytes before another thread reads or frees them. `handing_over` goes
/// before a reference leaves our code (dds_writecdr, ddsi_serdata_unref),
/// `taking_over` where a thread starts using a sample Cyclone gave it.
/// Both compile to nothing without TSan.
void handing_over(const ddsi_serdata* d);
void taking_over(const ddsi_serdata* d);

}  // namespace tinyline::dds::detail
