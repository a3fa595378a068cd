// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/writer.hpp>

#include <algorithm>
#include <limits>

#include <fmt/format.h>

#include <tinyline/bag/crc32.hpp>

#include "wire.hpp"

namespace tinyline::bag {

Writer::~Writer() {
  if (out_) (void)close();
}

Status Writer::open(const std::string& path, WriterOptions options) {
  auto f = std::make_unique<FileWritable>();
  if (Status s = f->open(path); !s.ok()) return s;
  return open(std::move(f), std::move(options));
}

Status Writer::open(std::unique_ptr<Writable> out, WriterOptions options) {
  if (out_) return {StatusCode::InvalidArgument, fmt::format("{}: writer is already open", out_->name())};
  if (!out) return {StatusCode::InvalidArgument, "writer opened with no sink"};
  if (options.chunk_size_bytes == 0) options.chunk_size_bytes = 1;
  options_ = std::move(options);
  out_ = std::move(out);
  closed_out_.reset();
  compressor_ = std::make_unique<Compressor>(options_.chunked ? options_.compression : Compression::None,
                                             options_.compression_level);
  error_ = {};
  schemas_.clear();
  channels_.clear();
  chunk_indexes_.clear();
  attachment_indexes_.clear();
  metadata_indexes_.clear();
  statistics_ = {};
  have_time_ = false;
  chunk_records_.clear();
  chunk_entries_.clear();
  chunk_channels_.clear();
  chunk_messages_ = 0;
  skip_compression_.clear();
  data_crc_ = 0;
  stats_ = {};

  if (Status s = emit(kMagic); !s.ok()) return s;
  scratch_.clear();
  serialize(Header{options_.profile, options_.library}, scratch_);
  return emit(scratch_);
}

Status Writer::fail(Status s) {
  if (error_.ok()) error_ = s;
  return s;
}

Status Writer::emit(std::span<const std::uint8_t> bytes, bool update_crc) {
  if (options_.crcs && update_crc) data_crc_ = crc32(bytes, data_crc_);
  Status s = out_->write(bytes);
  stats_.file_bytes = out_->size();
  if (!s.ok()) return fail(std::move(s));
  return s;
}

Status Writer::add_schema(Schema& schema) {
  if (!out_) return {StatusCode::NotOpen, "add_schema: writer is not open"};
  if (!error_.ok()) return error_;
  for (const auto& s : schemas_) {
    if (s.name == schema.name && s.encoding == schema.encoding && s.data == schema.data) {
      schema.id = s.id;
      return {};
    }
  }
  if (schemas_.size() >= std::numeric_limits<SchemaId>::max()) {
    return {StatusCode::InvalidArgument, fmt::format("{}: more than 65535 schemas", out_->name())};
  }
  schema.id = static_cast<SchemaId>(schemas_.size() + 1);
  schemas_.push_back(schema);
  scratch_.clear();
  serialize(schema, scratch_);
  return emit(scratch_);
}

Status Writer::add_channel(Channel& channel) {
  if (!out_) return {StatusCode::NotOpen, "add_channel: writer is not open"};
  if (!error_.ok()) return error_;
  if (channel.schema_id != 0 && channel.schema_id > schemas_.size()) {
    return {StatusCode::InvalidArgument, fmt::format("{}: channel '{}' refers to schema {}, which was never added",
                                                     out_->name(), channel.topic, channel.schema_id)};
  }
  for (std::size_t i = 1; i < channels_.size(); ++i) {
    const auto& c = channels_[i];
    if (c.topic == channel.topic && c.schema_id == channel.schema_id &&
        c.message_encoding == channel.message_encoding && c.metadata == channel.metadata) {
      channel.id = c.id;
      return {};
    }
  }
  if (channels_.empty()) channels_.emplace_back();  // id 0 unused: some readers treat it as "none"
  if (channels_.size() > std::numeric_limits<ChannelId>::max()) {
    return {StatusCode::InvalidArgument, fmt::format("{}: more than 65535 channels", out_->name())};
  }
  channel.id = static_cast<ChannelId>(channels_.size());
  channels_.push_back(channel);
  scratch_.clear();
  serialize(channel, scratch_);
  return emit(scratch_);
}

Status Writer::write(const Message& m) {
  if (!out_) return {StatusCode::NotOpen, "write: writer is not open"};
  if (!error_.ok()) return error_;
  if (m.channel_id == 0 || m.channel_id >= channels_.size()) {
    return {StatusCode::InvalidArgument,
            fmt::format("{}: message on channel {}, which was never added", out_->name(), m.channel_id)};
  }
  ++stats_.messages;
  stats_.message_bytes += m.data.size();
  ++statistics_.message_count;
  ++statistics_.channel_message_counts[m.channel_id];
  if (!have_time_) {
    statistics_.message_start_time = statistics_.message_end_time = m.log_time;
    have_time_ = true;
  } else {
    statistics_.message_start_time = std::min(statistics_.message_start_time, m.log_time);
    statistics_.message_end_time = std::max(statistics_.message_end_time, m.log_time);
  }

  if (!options_.chunked) {
    scratch_.clear();
    serialize(m, scratch_);
    return emit(scratch_);
  }
  // A message as large as a chunk gets a chunk of its own: readers of the
  // small topics then skip it without decompressing (its chunk index lists
  // only its channel).
  if (kRecordPrefix + 22 + m.data.size() >= options_.chunk_size_bytes) {
    if (Status s = close_chunk(); !s.ok()) return s;
    return write_large(m);
  }
  if (chunk_messages_ == 0) {
    chunk_start_ = chunk_end_ = m.log_time;
  } else {
    chunk_start_ = std::min(chunk_start_, m.log_time);
    chunk_end_ = std::max(chunk_end_, m.log_time);
  }
  ++chunk_messages_;
  if (options_.message_indexes) {
    if (chunk_entries_.size() <= m.channel_id) chunk_entries_.resize(m.channel_id + 1);
    auto& entries = chunk_entries_[m.channel_id];
    if (entries.empty()) chunk_channels_.push_back(m.channel_id);
    entries.push_back(MessageIndexEntry{m.log_time, chunk_records_.size()});
  }
  serialize(m, chunk_records_);
  if (chunk_records_.size() >= options_.chunk_size_bytes) return close_chunk();
  return {};
}

Status Writer::write_large(const Message& m) {
  chunk_start_ = chunk_end_ = m.log_time;
  chunk_messages_ = 1;
  if (options_.message_indexes) {
    if (chunk_entries_.size() <= m.channel_id) chunk_entries_.resize(m.channel_id + 1);
    chunk_entries_[m.channel_id].push_back(MessageIndexEntry{m.log_time, 0});
    chunk_channels_.push_back(m.channel_id);
  }
  if (skip_compression_.size() <= m.channel_id) skip_compression_.resize(m.channel_id + 1, 0);
  std::uint8_t& skip = skip_compression_[m.channel_id];
  if (compressor_->type() != Compression::None && skip == 0) {
    serialize(m, chunk_records_);  // the compressor wants one contiguous buffer
    return close_chunk(m.channel_id);
  }
  if (skip > 0) --skip;
  // Stored as is: the record prefix, then the caller's bytes, with no copy.
  prefix_.clear();
  serialize_message_prefix(m, m.data.size(), prefix_);
  const std::uint32_t crc = options_.crcs ? crc32(m.data, crc32(prefix_)) : 0;
  return emit_chunk(prefix_, m.data, crc, prefix_.size() + m.data.size(), "");
}

Status Writer::close_chunk(ChannelId large_channel) {
  if (chunk_records_.empty()) return {};
  const std::uint32_t crc = options_.crcs ? crc32(chunk_records_) : 0;
  std::span<const std::uint8_t> stored = chunk_records_;  // stored as is: no copy
  std::string_view comp;
  if (compressor_->type() != Compression::None) {
    std::span<const std::uint8_t> packed;
    if (Status s = compressor_->compress(chunk_records_, compressed_, packed); !s.ok()) {
      return fail(Status(s.code, fmt::format("{}: chunk {}: {}", out_->name(), statistics_.chunk_count, s.message)));
    }
    if (options_.skip_incompressible && packed.size() * 100 > chunk_records_.size() * 97) {
      // Under 3% saved: store it, so readers need not decompress it either; and
      // do not even try the next few large messages of the same topic.
      if (large_channel != 0) skip_compression_[large_channel] = kSkipAfterIncompressible;
    } else {
      stored = packed;
      comp = mcap_name(compressor_->type());
    }
  }
  return emit_chunk(stored, {}, crc, chunk_records_.size(), comp);
}

Status Writer::emit_chunk(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b, std::uint32_t crc,
                          std::uint64_t uncompressed_size, std::string_view comp) {
  ChunkIndex index;
  index.message_start_time = chunk_messages_ ? chunk_start_ : 0;
  index.message_end_time = chunk_messages_ ? chunk_end_ : 0;
  index.chunk_start_offset = out_->size();
  index.compression = std::string(comp);
  index.compressed_size = a.size() + b.size();
  index.uncompressed_size = uncompressed_size;

  // The chunk record: its fixed fields, then the stored bytes as they are (no copy).
  scratch_.clear();
  scratch_.push_back(static_cast<std::uint8_t>(Opcode::Chunk));
  const std::uint64_t content = 8 + 8 + 8 + 4 + 4 + comp.size() + 8 + index.compressed_size;
  wire::put(scratch_, content);
  wire::put(scratch_, index.message_start_time);
  wire::put(scratch_, index.message_end_time);
  wire::put<std::uint64_t>(scratch_, uncompressed_size);
  wire::put(scratch_, crc);
  wire::put_string(scratch_, comp);
  wire::put<std::uint64_t>(scratch_, index.compressed_size);
  if (Status s = emit(scratch_); !s.ok()) return s;
  // A stored chunk's bytes are the ones its CRC covers: fold that CRC into the
  // data CRC instead of reading them a second time.
  const bool fold = comp.empty() && crc != 0;
  if (Status s = emit(a, !fold); !s.ok()) return s;
  if (!b.empty()) {
    if (Status s = emit(b, !fold); !s.ok()) return s;
  }
  if (fold) data_crc_ = crc32_combine(data_crc_, crc, index.compressed_size);
  index.chunk_length = kRecordPrefix + content;

  if (options_.message_indexes) {
    std::sort(chunk_channels_.begin(), chunk_channels_.end());
    scratch_.clear();
    const std::uint64_t base = out_->size();
    MessageIndex mi;
    for (ChannelId id : chunk_channels_) {
      auto& entries = chunk_entries_[id];
      // Log-time order lets an indexed reader merge chunks without sorting.
      std::stable_sort(entries.begin(), entries.end(),
                       [](const MessageIndexEntry& x, const MessageIndexEntry& y) { return x.log_time < y.log_time; });
      index.message_index_offsets[id] = base + scratch_.size();
      mi.channel_id = id;
      mi.records.swap(entries);
      serialize(mi, scratch_);
      mi.records.swap(entries);
      entries.clear();
    }
    index.message_index_length = scratch_.size();
    if (Status s = emit(scratch_); !s.ok()) return s;
  }
  chunk_channels_.clear();

  ++statistics_.chunk_count;
  ++stats_.chunks;
  stats_.uncompressed_bytes += uncompressed_size;
  if (options_.summary) chunk_indexes_.push_back(std::move(index));
  chunk_records_.clear();
  chunk_messages_ = 0;
  if (options_.flush_every_chunk) {
    if (Status s = out_->flush(); !s.ok()) return fail(std::move(s));
  }
  return {};
}

Status Writer::write(const Attachment& a) {
  if (!out_) return {StatusCode::NotOpen, "write: writer is not open"};
  if (!error_.ok()) return error_;
  AttachmentIndex idx;
  idx.offset = out_->size();
  idx.log_time = a.log_time;
  idx.create_time = a.create_time;
  idx.data_size = a.data.size();
  idx.name = a.name;
  idx.media_type = a.media_type;
  scratch_.clear();
  serialize(a, scratch_, options_.crcs);
  idx.length = scratch_.size();
  if (Status s = emit(scratch_); !s.ok()) return s;
  ++statistics_.attachment_count;
  if (options_.summary) attachment_indexes_.push_back(std::move(idx));
  return {};
}

Status Writer::write(const Metadata& m) {
  if (!out_) return {StatusCode::NotOpen, "write: writer is not open"};
  if (!error_.ok()) return error_;
  MetadataIndex idx;
  idx.offset = out_->size();
  idx.name = m.name;
  scratch_.clear();
  serialize(m, scratch_);
  idx.length = scratch_.size();
  if (Status s = emit(scratch_); !s.ok()) return s;
  ++statistics_.metadata_count;
  if (options_.summary) metadata_indexes_.push_back(std::move(idx));
  return {};
}

Status Writer::flush() {
  if (!out_) return {StatusCode::NotOpen, "flush: writer is not open"};
  if (!error_.ok()) return error_;
  if (Status s = close_chunk(); !s.ok()) return s;
  if (Status s = out_->flush(); !s.ok()) return fail(std::move(s));
  return {};
}

std::vector<std::uint8_t> Writer::summary_section(std::uint64_t summary_start, std::vector<SummaryOffset>& offsets) {
  std::vector<std::uint8_t> summary;
  if (!options_.summary) return summary;
  auto group = [&](Opcode op, auto&& write_records) {
    const std::size_t before = summary.size();
    write_records();
    if (summary.size() > before) {
      offsets.push_back(SummaryOffset{static_cast<std::uint8_t>(op), summary_start + before, summary.size() - before});
    }
  };
  statistics_.schema_count = static_cast<std::uint16_t>(schemas_.size());
  statistics_.channel_count = static_cast<std::uint32_t>(channels_.empty() ? 0 : channels_.size() - 1);
  group(Opcode::Schema, [&] {
    for (const auto& s : schemas_) serialize(s, summary);
  });
  group(Opcode::Channel, [&] {
    for (std::size_t i = 1; i < channels_.size(); ++i) serialize(channels_[i], summary);
  });
  group(Opcode::Statistics, [&] { serialize(statistics_, summary); });
  group(Opcode::ChunkIndex, [&] {
    for (const auto& c : chunk_indexes_) serialize(c, summary);
  });
  group(Opcode::AttachmentIndex, [&] {
    for (const auto& a : attachment_indexes_) serialize(a, summary);
  });
  group(Opcode::MetadataIndex, [&] {
    for (const auto& m : metadata_indexes_) serialize(m, summary);
  });
  return summary;
}

Status Writer::write_summary_and_footer() {
  std::vector<SummaryOffset> offsets;
  const std::uint64_t summary_start = out_->size();
  std::vector<std::uint8_t> summary = summary_section(summary_start, offsets);
  Footer footer;
  footer.summary_start = summary.empty() ? 0 : summary_start;
  if (!summary.empty() && options_.summary_offsets) {
    footer.summary_offset_start = summary_start + summary.size();
    for (const auto& o : offsets) serialize(o, summary);
  }
  std::vector<std::uint8_t> tail;
  serialize(footer, tail);  // summary_crc patched below
  if (options_.crcs && !summary.empty()) {
    // The summary CRC runs from the summary start through the footer's summary_offset_start.
    std::uint32_t crc = crc32(summary);
    crc = crc32(std::span(tail).first(tail.size() - 4), crc);
    footer.summary_crc = crc;
    tail.clear();
    serialize(footer, tail);
  }
  tail.insert(tail.end(), kMagic.begin(), kMagic.end());
  Status result = out_->write(summary);
  if (result.ok()) result = out_->write(tail);
  stats_.file_bytes = out_->size();
  return result;
}

Status Writer::close() {
  if (!out_) return error_;
  Status result = error_;
  if (result.ok()) result = close_chunk();
  if (result.ok()) {
    scratch_.clear();
    serialize(DataEnd{options_.crcs ? data_crc_ : 0}, scratch_);
    result = emit(scratch_);
  }
  if (result.ok()) result = write_summary_and_footer();
  if (result.ok()) {
    result = out_->close();
  } else {
    out_->abandon();  // an unfinished file never replaces what the path held
  }
  closed_out_ = std::move(out_);
  if (!result.ok()) error_ = result;
  return result;
}

}  // namespace tinyline::bag
