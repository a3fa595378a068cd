// SPDX-License-Identifier: Apache-2.0
// The records of an MCAP file (MCAP format specification, major version 0).
//
//   <magic><Header><data section>[<summary section>][<summary offsets>]<Footer><magic>
//
// Every record is <opcode u8><content length u64><content>; integers are
// little-endian, strings and byte arrays carry a u32 length (chunk records and
// attachments a u64 one), maps a u32 byte length. Readers ignore bytes after
// the fields they know (records may grow) and skip unknown opcodes.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <tinyline/bag/status.hpp>

namespace tinyline::bag {

using SchemaId = std::uint16_t;
using ChannelId = std::uint16_t;
/// Nanoseconds since an epoch the recording chose (unix time, or sim time).
using Timestamp = std::uint64_t;
using KeyValueMap = std::map<std::string, std::string>;

enum class Opcode : std::uint8_t {
  Header = 0x01,
  Footer = 0x02,
  Schema = 0x03,
  Channel = 0x04,
  Message = 0x05,
  Chunk = 0x06,
  MessageIndex = 0x07,
  ChunkIndex = 0x08,
  Attachment = 0x09,
  AttachmentIndex = 0x0A,
  Statistics = 0x0B,
  Metadata = 0x0C,
  MetadataIndex = 0x0D,
  SummaryOffset = 0x0E,
  DataEnd = 0x0F,
};

/// "Chunk", "Message", ... or "unknown(0x80)".
std::string opcode_name(std::uint8_t op);

inline constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
/// Opcode + length prefix of every record.
inline constexpr std::uint64_t kRecordPrefix = 9;
/// A footer record with its prefix (9 + 8 + 8 + 4).
inline constexpr std::uint64_t kFooterRecordSize = 29;

struct Header {
  std::string profile;  ///< "ros2" for ROS 2 bags
  std::string library;  ///< the writer's name and version
};

struct Footer {
  std::uint64_t summary_start = 0;         ///< file offset of the summary section, 0 if none
  std::uint64_t summary_offset_start = 0;  ///< file offset of the summary offset section, 0 if none
  std::uint32_t summary_crc = 0;  ///< CRC32 from summary_start through summary_offset_start of the footer; 0: none
};

struct Schema {
  SchemaId id = 0;       ///< never 0 (0 means "no schema")
  std::string name;      ///< "sensor_msgs/msg/LaserScan"
  std::string encoding;  ///< "ros2msg"
  std::string data;      ///< the schema text (bytes in general)
  bool operator==(const Schema&) const = default;
};

struct Channel {
  ChannelId id = 0;
  SchemaId schema_id = 0;  ///< 0: schemaless
  std::string topic;
  std::string message_encoding;  ///< "cdr"
  KeyValueMap metadata;          ///< ros2: offered_qos_profiles
  bool operator==(const Channel&) const = default;
};

/// A message; `data` points into a buffer owned by whoever produced it.
struct Message {
  ChannelId channel_id = 0;
  std::uint32_t sequence = 0;
  Timestamp log_time = 0;      ///< when it was recorded
  Timestamp publish_time = 0;  ///< when it was published (log_time if unknown)
  std::span<const std::uint8_t> data;
};

struct Chunk {
  Timestamp message_start_time = 0;
  Timestamp message_end_time = 0;
  std::uint64_t uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;     ///< 0: not computed
  std::string compression;                ///< "", "lz4" or "zstd"
  std::span<const std::uint8_t> records;  ///< compressed records
};

struct MessageIndexEntry {
  Timestamp log_time = 0;
  std::uint64_t offset = 0;  ///< into the uncompressed chunk records
};

struct MessageIndex {
  ChannelId channel_id = 0;
  std::vector<MessageIndexEntry> records;
};

struct ChunkIndex {
  Timestamp message_start_time = 0;
  Timestamp message_end_time = 0;
  std::uint64_t chunk_start_offset = 0;                      ///< file offset of the chunk record
  std::uint64_t chunk_length = 0;                            ///< the chunk record's full length, prefix included
  std::map<ChannelId, std::uint64_t> message_index_offsets;  ///< file offset of each channel's message index
  std::uint64_t message_index_length = 0;
  std::string compression;
  std::uint64_t compressed_size = 0;
  std::uint64_t uncompressed_size = 0;
};

struct Attachment {
  Timestamp log_time = 0;
  Timestamp create_time = 0;
  std::string name;
  std::string media_type;
  std::span<const std::uint8_t> data;
  std::uint32_t crc = 0;  ///< of the preceding fields; 0: not computed
};

struct AttachmentIndex {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  Timestamp log_time = 0;
  Timestamp create_time = 0;
  std::uint64_t data_size = 0;
  std::string name;
  std::string media_type;
};

struct Statistics {
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0;
  std::uint32_t attachment_count = 0;
  std::uint32_t metadata_count = 0;
  std::uint32_t chunk_count = 0;
  Timestamp message_start_time = 0;
  Timestamp message_end_time = 0;
  std::map<ChannelId, std::uint64_t> channel_message_counts;
};

struct Metadata {
  std::string name;
  KeyValueMap metadata;
};

struct MetadataIndex {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::string name;
};

struct SummaryOffset {
  std::uint8_t group_opcode = 0;
  std::uint64_t group_start = 0;
  std::uint64_t group_length = 0;
};

struct DataEnd {
  std::uint32_t data_section_crc = 0;
};

// ---------------------------------------------------------------------------- parsing
//
// Each parser reads one record's content (the bytes after the 9-byte prefix).
// `where` names the record for error messages ("scans.mcap: Chunk at byte
// 1234"). Spans in the result point into `content`.

Status parse(std::span<const std::uint8_t> content, Header& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Footer& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Schema& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Channel& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Message& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Chunk& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, MessageIndex& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, ChunkIndex& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Attachment& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, AttachmentIndex& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Statistics& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, Metadata& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, MetadataIndex& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, SummaryOffset& out, std::string_view where);
Status parse(std::span<const std::uint8_t> content, DataEnd& out, std::string_view where);

// ---------------------------------------------------------------------------- serialization
//
// Each appends a whole record (prefix included) to `out`.

void serialize(const Header& r, std::vector<std::uint8_t>& out);
void serialize(const Footer& r, std::vector<std::uint8_t>& out);
void serialize(const Schema& r, std::vector<std::uint8_t>& out);
void serialize(const Channel& r, std::vector<std::uint8_t>& out);
void serialize(const Message& r, std::vector<std::uint8_t>& out);
void serialize(const Chunk& r, std::vector<std::uint8_t>& out);
void serialize(const MessageIndex& r, std::vector<std::uint8_t>& out);
void serialize(const ChunkIndex& r, std::vector<std::uint8_t>& out);
/// Computes the CRC when `with_crc`; the record's own crc field is ignored.
void serialize(const Attachment& r, std::vector<std::uint8_t>& out, bool with_crc = true);
void serialize(const AttachmentIndex& r, std::vector<std::uint8_t>& out);
void serialize(const Statistics& r, std::vector<std::uint8_t>& out);
void serialize(const Metadata& r, std::vector<std::uint8_t>& out);
void serialize(const MetadataIndex& r, std::vector<std::uint8_t>& out);
void serialize(const SummaryOffset& r, std::vector<std::uint8_t>& out);
void serialize(const DataEnd& r, std::vector<std::uint8_t>& out);

/// The prefix of a Message record, for writers that append the data themselves.
void serialize_message_prefix(const Message& r, std::uint64_t data_size, std::vector<std::uint8_t>& out);

/// CRC of an attachment record's content up to (not including) its crc field.
std::uint32_t attachment_crc(std::span<const std::uint8_t> content_without_crc);

}  // namespace tinyline::bag
