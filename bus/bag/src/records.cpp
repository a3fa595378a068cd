// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/records.hpp>

#include <fmt/format.h>

#include <tinyline/bag/crc32.hpp>

#include "wire.hpp"

namespace tinyline::bag {

using wire::begin_record;
using wire::Cursor;
using wire::end_record;
using wire::put;
using wire::put_string;

std::string opcode_name(std::uint8_t op) {
  switch (static_cast<Opcode>(op)) {
    case Opcode::Header: return "Header";
    case Opcode::Footer: return "Footer";
    case Opcode::Schema: return "Schema";
    case Opcode::Channel: return "Channel";
    case Opcode::Message: return "Message";
    case Opcode::Chunk: return "Chunk";
    case Opcode::MessageIndex: return "MessageIndex";
    case Opcode::ChunkIndex: return "ChunkIndex";
    case Opcode::Attachment: return "Attachment";
    case Opcode::AttachmentIndex: return "AttachmentIndex";
    case Opcode::Statistics: return "Statistics";
    case Opcode::Metadata: return "Metadata";
    case Opcode::MetadataIndex: return "MetadataIndex";
    case Opcode::SummaryOffset: return "SummaryOffset";
    case Opcode::DataEnd: return "DataEnd";
  }
  return fmt::format("unknown(0x{:02x})", op);
}

// ---------------------------------------------------------------------------- parsing

Status parse(std::span<const std::uint8_t> content, Header& out, std::string_view where) {
  Cursor c(content, where);
  out.profile = c.get_string("profile");
  out.library = c.get_string("library");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Footer& out, std::string_view where) {
  Cursor c(content, where);
  out.summary_start = c.get<std::uint64_t>("summary_start");
  out.summary_offset_start = c.get<std::uint64_t>("summary_offset_start");
  out.summary_crc = c.get<std::uint32_t>("summary_crc");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Schema& out, std::string_view where) {
  Cursor c(content, where);
  out.id = c.get<std::uint16_t>("id");
  out.name = c.get_string("name");
  out.encoding = c.get_string("encoding");
  auto data = c.get_prefixed32("data");
  out.data.assign(reinterpret_cast<const char*>(data.data()), data.size());
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Channel& out, std::string_view where) {
  Cursor c(content, where);
  out.id = c.get<std::uint16_t>("id");
  out.schema_id = c.get<std::uint16_t>("schema_id");
  out.topic = c.get_string("topic");
  out.message_encoding = c.get_string("message_encoding");
  out.metadata = c.get_map("metadata");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Message& out, std::string_view where) {
  Cursor c(content, where);
  out.channel_id = c.get<std::uint16_t>("channel_id");
  out.sequence = c.get<std::uint32_t>("sequence");
  out.log_time = c.get<std::uint64_t>("log_time");
  out.publish_time = c.get<std::uint64_t>("publish_time");
  out.data = c.rest();
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Chunk& out, std::string_view where) {
  Cursor c(content, where);
  out.message_start_time = c.get<std::uint64_t>("message_start_time");
  out.message_end_time = c.get<std::uint64_t>("message_end_time");
  out.uncompressed_size = c.get<std::uint64_t>("uncompressed_size");
  out.uncompressed_crc = c.get<std::uint32_t>("uncompressed_crc");
  out.compression = c.get_string("compression");
  const auto n = c.get<std::uint64_t>("records length");
  out.records = c.get_bytes(n, "records");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, MessageIndex& out, std::string_view where) {
  Cursor c(content, where);
  out.channel_id = c.get<std::uint16_t>("channel_id");
  auto bytes = c.get_prefixed32("records");
  if (!c.ok()) return c.status();
  if (bytes.size() % 16 != 0) {
    c.fail(fmt::format("records array of {} bytes is not a multiple of 16", bytes.size()));
    return c.status();
  }
  out.records.resize(bytes.size() / 16);
  for (std::size_t i = 0; i < out.records.size(); ++i) {
    out.records[i].log_time = wire::load<std::uint64_t>(bytes.data() + 16 * i);
    out.records[i].offset = wire::load<std::uint64_t>(bytes.data() + 16 * i + 8);
  }
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, ChunkIndex& out, std::string_view where) {
  Cursor c(content, where);
  out.message_start_time = c.get<std::uint64_t>("message_start_time");
  out.message_end_time = c.get<std::uint64_t>("message_end_time");
  out.chunk_start_offset = c.get<std::uint64_t>("chunk_start_offset");
  out.chunk_length = c.get<std::uint64_t>("chunk_length");
  auto offsets = c.get_prefixed32("message_index_offsets");
  if (!c.ok()) return c.status();
  if (offsets.size() % 10 != 0) {
    c.fail(fmt::format("message_index_offsets of {} bytes is not a multiple of 10", offsets.size()));
    return c.status();
  }
  out.message_index_offsets.clear();
  for (std::size_t i = 0; i < offsets.size(); i += 10) {
    out.message_index_offsets[wire::load<std::uint16_t>(offsets.data() + i)] =
        wire::load<std::uint64_t>(offsets.data() + i + 2);
  }
  out.message_index_length = c.get<std::uint64_t>("message_index_length");
  out.compression = c.get_string("compression");
  out.compressed_size = c.get<std::uint64_t>("compressed_size");
  out.uncompressed_size = c.get<std::uint64_t>("uncompressed_size");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Attachment& out, std::string_view where) {
  Cursor c(content, where);
  out.log_time = c.get<std::uint64_t>("log_time");
  out.create_time = c.get<std::uint64_t>("create_time");
  out.name = c.get_string("name");
  out.media_type = c.get_string("media_type");
  const auto n = c.get<std::uint64_t>("data length");
  out.data = c.get_bytes(n, "data");
  out.crc = c.get<std::uint32_t>("crc");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, AttachmentIndex& out, std::string_view where) {
  Cursor c(content, where);
  out.offset = c.get<std::uint64_t>("offset");
  out.length = c.get<std::uint64_t>("length");
  out.log_time = c.get<std::uint64_t>("log_time");
  out.create_time = c.get<std::uint64_t>("create_time");
  out.data_size = c.get<std::uint64_t>("data_size");
  out.name = c.get_string("name");
  out.media_type = c.get_string("media_type");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Statistics& out, std::string_view where) {
  Cursor c(content, where);
  out.message_count = c.get<std::uint64_t>("message_count");
  out.schema_count = c.get<std::uint16_t>("schema_count");
  out.channel_count = c.get<std::uint32_t>("channel_count");
  out.attachment_count = c.get<std::uint32_t>("attachment_count");
  out.metadata_count = c.get<std::uint32_t>("metadata_count");
  out.chunk_count = c.get<std::uint32_t>("chunk_count");
  out.message_start_time = c.get<std::uint64_t>("message_start_time");
  out.message_end_time = c.get<std::uint64_t>("message_end_time");
  auto counts = c.get_prefixed32("channel_message_counts");
  if (!c.ok()) return c.status();
  if (counts.size() % 10 != 0) {
    c.fail(fmt::format("channel_message_counts of {} bytes is not a multiple of 10", counts.size()));
    return c.status();
  }
  out.channel_message_counts.clear();
  for (std::size_t i = 0; i < counts.size(); i += 10) {
    out.channel_message_counts[wire::load<std::uint16_t>(counts.data() + i)] =
        wire::load<std::uint64_t>(counts.data() + i + 2);
  }
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, Metadata& out, std::string_view where) {
  Cursor c(content, where);
  out.name = c.get_string("name");
  out.metadata = c.get_map("metadata");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, MetadataIndex& out, std::string_view where) {
  Cursor c(content, where);
  out.offset = c.get<std::uint64_t>("offset");
  out.length = c.get<std::uint64_t>("length");
  out.name = c.get_string("name");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, SummaryOffset& out, std::string_view where) {
  Cursor c(content, where);
  out.group_opcode = c.get<std::uint8_t>("group_opcode");
  out.group_start = c.get<std::uint64_t>("group_start");
  out.group_length = c.get<std::uint64_t>("group_length");
  return c.status();
}

Status parse(std::span<const std::uint8_t> content, DataEnd& out, std::string_view where) {
  Cursor c(content, where);
  out.data_section_crc = c.get<std::uint32_t>("data_section_crc");
  return c.status();
}

// ---------------------------------------------------------------------------- serialization

void serialize(const Header& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Header);
  put_string(out, r.profile);
  put_string(out, r.library);
  end_record(out, p);
}

void serialize(const Footer& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Footer);
  put(out, r.summary_start);
  put(out, r.summary_offset_start);
  put(out, r.summary_crc);
  end_record(out, p);
}

void serialize(const Schema& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Schema);
  put(out, r.id);
  put_string(out, r.name);
  put_string(out, r.encoding);
  put_string(out, r.data);
  end_record(out, p);
}

void serialize(const Channel& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Channel);
  put(out, r.id);
  put(out, r.schema_id);
  put_string(out, r.topic);
  put_string(out, r.message_encoding);
  wire::put_map(out, r.metadata);
  end_record(out, p);
}

void serialize_message_prefix(const Message& r, std::uint64_t data_size, std::vector<std::uint8_t>& out) {
  out.push_back(static_cast<std::uint8_t>(Opcode::Message));
  put<std::uint64_t>(out, 2 + 4 + 8 + 8 + data_size);
  put(out, r.channel_id);
  put(out, r.sequence);
  put(out, r.log_time);
  put(out, r.publish_time);
}

void serialize(const Message& r, std::vector<std::uint8_t>& out) {
  serialize_message_prefix(r, r.data.size(), out);
  wire::put_bytes(out, r.data);
}

void serialize(const Chunk& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Chunk);
  put(out, r.message_start_time);
  put(out, r.message_end_time);
  put(out, r.uncompressed_size);
  put(out, r.uncompressed_crc);
  put_string(out, r.compression);
  put<std::uint64_t>(out, r.records.size());
  wire::put_bytes(out, r.records);
  end_record(out, p);
}

void serialize(const MessageIndex& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::MessageIndex);
  put(out, r.channel_id);
  put(out, static_cast<std::uint32_t>(r.records.size() * 16));
  for (const auto& e : r.records) {
    put(out, e.log_time);
    put(out, e.offset);
  }
  end_record(out, p);
}

void serialize(const ChunkIndex& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::ChunkIndex);
  put(out, r.message_start_time);
  put(out, r.message_end_time);
  put(out, r.chunk_start_offset);
  put(out, r.chunk_length);
  put(out, static_cast<std::uint32_t>(r.message_index_offsets.size() * 10));
  for (const auto& [id, off] : r.message_index_offsets) {
    put(out, id);
    put(out, off);
  }
  put(out, r.message_index_length);
  put_string(out, r.compression);
  put(out, r.compressed_size);
  put(out, r.uncompressed_size);
  end_record(out, p);
}

std::uint32_t attachment_crc(std::span<const std::uint8_t> content_without_crc) { return crc32(content_without_crc); }

void serialize(const Attachment& r, std::vector<std::uint8_t>& out, bool with_crc) {
  const auto p = begin_record(out, Opcode::Attachment);
  const auto content_start = out.size();
  put(out, r.log_time);
  put(out, r.create_time);
  put_string(out, r.name);
  put_string(out, r.media_type);
  put<std::uint64_t>(out, r.data.size());
  wire::put_bytes(out, r.data);
  const std::uint32_t crc =
      with_crc ? attachment_crc(std::span(out).subspan(content_start, out.size() - content_start)) : 0;
  put(out, crc);
  end_record(out, p);
}

void serialize(const AttachmentIndex& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::AttachmentIndex);
  put(out, r.offset);
  put(out, r.length);
  put(out, r.log_time);
  put(out, r.create_time);
  put(out, r.data_size);
  put_string(out, r.name);
  put_string(out, r.media_type);
  end_record(out, p);
}

void serialize(const Statistics& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Statistics);
  put(out, r.message_count);
  put(out, r.schema_count);
  put(out, r.channel_count);
  put(out, r.attachment_count);
  put(out, r.metadata_count);
  put(out, r.chunk_count);
  put(out, r.message_start_time);
  put(out, r.message_end_time);
  put(out, static_cast<std::uint32_t>(r.channel_message_counts.size() * 10));
  for (const auto& [id, n] : r.channel_message_counts) {
    put(out, id);
    put(out, n);
  }
  end_record(out, p);
}

void serialize(const Metadata& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::Metadata);
  put_string(out, r.name);
  wire::put_map(out, r.metadata);
  end_record(out, p);
}

void serialize(const MetadataIndex& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::MetadataIndex);
  put(out, r.offset);
  put(out, r.length);
  put_string(out, r.name);
  end_record(out, p);
}

void serialize(const SummaryOffset& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::SummaryOffset);
  put(out, r.group_opcode);
  put(out, r.group_start);
  put(out, r.group_length);
  end_record(out, p);
}

void serialize(const DataEnd& r, std::vector<std::uint8_t>& out) {
  const auto p = begin_record(out, Opcode::DataEnd);
  put(out, r.data_section_crc);
  end_record(out, p);
}

}  // namespace tinyline::bag
