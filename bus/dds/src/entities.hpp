// SPDX-License-Identifier: Apache-2.0
// Shared helpers of the DDS sources: QoS mapping, topic creation, errors.
#pragma once

#include <dds/dds.h>

#include <dds/ddsi/ddsi_sertype.h>

#include <string>
#include <vector>

#include <tinyline/dds/participant.hpp>
#include <tinyline/msg/type_support.hpp>

namespace tinyline::dds::detail {

/// "what: Cyclone's reason" as a DdsError.
[[noreturn]] void fail(const std::string& what, dds_return_t rc);

/// Owns a dds_qos_t.
struct Qos {
  dds_qos_t* q = dds_create_qos();
  Qos() = default;
  Qos(const Qos&) = delete;
  Qos& operator=(const Qos&) = delete;
  ~Qos() { dds_delete_qos(q); }
};

/// The DDS QoS of an endpoint: reliability, durability, history, XCDR1 only,
/// the type's hash (as ROS 2 puts it, "typehash=RIHS01_...;") and our
/// identity as user data; readers ignore writers of their own participant.
void fill_qos(Qos& out, const EndpointQos& q, bool reader, const Identity& who, const msg::TypeSupport* type);
EndpointQos read_qos(const dds_qos_t* q);
Identity read_identity(const dds_qos_t* q);

/// A DDS topic entity for `dds_topic` with our raw sertype, and the sertype
/// the domain actually uses for it (valid while the topic lives). Throws DdsError.
struct TopicHandle {
  dds_entity_t topic = 0;
  const ddsi_sertype* sertype = nullptr;
};
TopicHandle create_topic(dds_entity_t participant, const std::string& dds_topic, const std::string& dds_type,
                         const msg::TypeSupport* type, std::size_t max_sample_bytes);

/// Names of QoS policies (for incompatibility reports).
const char* policy_name(std::uint32_t policy_id);

std::string guid_hex(const dds_guid_t& g);

}  // namespace tinyline::dds::detail
