// SPDX-License-Identifier: Apache-2.0
#include <algorithm>
#include <cstring>

#include <fmt/format.h>

#include <tinyline/bag/compression.hpp>
#include <tinyline/bag/crc32.hpp>
#include <tinyline/bag/reader.hpp>

#include "wire.hpp"

namespace tinyline::bag {

struct LinearReader::Impl {
  Readable& src;
  LinearReaderOptions opt;
  Status status;
  std::vector<ReadProblem> problems;
  std::map<SchemaId, Schema> schemas;
  std::map<ChannelId, Channel> channels;

  enum class State { Start, Records, InChunk, Done } state = State::Start;
  std::uint64_t pos = 0;       // next record in the file
  std::uint32_t data_crc = 0;  // over every byte before the Data End record
  bool data_end = false;
  bool footer = false;

  std::vector<std::uint8_t> rec;  // content of the current top-level record
  Header header;
  Metadata metadata;
  Chunk chunk;
  std::uint64_t chunk_offset = 0;
  std::vector<std::uint8_t> chunk_buf;  // decompressed records
  std::size_t chunk_pos = 0;
  std::map<SchemaId, Schema> known_schemas;  // know(): trusted over the file's copies
  std::map<ChannelId, Channel> known_channels;
  bool single_record = false;  // read_chunk_at(): stop after that record
  bool crc_gap = false;        // bytes were skipped: no data section CRC

  Impl(Readable& s, LinearReaderOptions o) : src(s), opt(o) {}

  std::string where(std::uint64_t offset, std::uint8_t op) const {
    return fmt::format("{}: {} record at byte {}", src.name(), opcode_name(op), offset);
  }
  std::string where_in_chunk(std::size_t inner, std::uint8_t op) const {
    return fmt::format("{}: {} record at byte {} of the chunk at byte {}", src.name(), opcode_name(op), inner,
                       chunk_offset);
  }

  // A problem: an error (stop) in strict mode; noted and stepped over in recovery mode.
  bool problem(std::uint64_t offset, Status s, bool chunk_dropped = false) {
    if (opt.recover) {
      problems.push_back(ReadProblem{offset, std::move(s), chunk_dropped});
      return true;
    }
    status = std::move(s);
    state = State::Done;
    return false;
  }

  bool fatal(Status s) {
    status = std::move(s);
    state = State::Done;
    return false;
  }

  // The end of the file came before a Data End record or footer.
  bool truncated_end(std::uint64_t offset, std::string what) {
    Status s(StatusCode::Truncated,
             fmt::format("{} (the writer did not finish; `tinyline bag recover` rewrites what is there)", what));
    state = State::Done;
    if (opt.recover) {
      problems.push_back(ReadProblem{offset, std::move(s), false});
      return false;
    }
    status = std::move(s);
    return false;
  }

  bool read_start() {
    const std::uint64_t size = src.size();
    std::uint8_t magic[8];
    if (size < 8) {
      return fatal({StatusCode::BadMagic,
                    fmt::format("{}: {} bytes is too short for an MCAP file (no magic)", src.name(), size)});
    }
    if (Status s = src.read(0, magic); !s.ok()) return fatal(std::move(s));
    if (std::memcmp(magic, kMagic.data(), 8) != 0) {
      return fatal({StatusCode::BadMagic, fmt::format("{}: does not start with the MCAP magic", src.name())});
    }
    if (opt.validate_crcs) data_crc = crc32(std::span<const std::uint8_t>(magic, 8));
    pos = 8;
    state = State::Records;
    return true;
  }

  // Reads the prefix at `pos`; returns false at the end (with state/status set).
  bool read_prefix(std::uint8_t& op, std::uint64_t& len) {
    const std::uint64_t size = src.size();
    if (pos == size) {
      return truncated_end(
          pos, fmt::format("{}: file ends at byte {} without a Data End record or footer", src.name(), pos));
    }
    if (size - pos < kRecordPrefix) {
      return truncated_end(pos, fmt::format("{}: file ends inside a record prefix at byte {}", src.name(), pos));
    }
    std::uint8_t p[9];
    if (Status s = src.read(pos, p); !s.ok()) return fatal(std::move(s));
    op = p[0];
    std::memcpy(&len, p + 1, 8);
    if (len > size - pos - kRecordPrefix) {
      return truncated_end(pos, fmt::format("{} claims {} content bytes but the file has {} after it", where(pos, op),
                                            len, size - pos - kRecordPrefix));
    }
    if (len > opt.max_record_bytes) {
      return fatal({StatusCode::LimitExceeded, fmt::format("{} is {} bytes, more than the limit of {}", where(pos, op),
                                                           len, opt.max_record_bytes)});
    }
    return true;
  }

  // Reads the content of the record at `pos` into rec (with the data CRC).
  bool read_content(std::uint8_t op, std::uint64_t len) {
    rec.resize(static_cast<std::size_t>(len));
    if (Status s = src.read(pos + kRecordPrefix, rec); !s.ok()) return fatal(std::move(s));
    if (opt.validate_crcs && !data_end) {
      std::uint8_t p[9];
      p[0] = op;
      std::memcpy(p + 1, &len, 8);
      data_crc = crc32(std::span<const std::uint8_t>(p, 9), data_crc);
      data_crc = crc32(rec, data_crc);
    }
    return true;
  }

  enum class Step { Emit, Skip, Stop };

  bool next(LinearRecord& out) {
    while (state != State::Done) {
      if (state == State::Start) {
        if (!read_start()) return false;
        continue;
      }
      if (state == State::InChunk) {
        if (next_in_chunk(out)) return true;
        if (single_record && state == State::Records) state = State::Done;  // the one chunk asked for is done
        continue;
      }
      const Step step = next_top_level(out);
      if (step == Step::Emit) return true;
      if (step == Step::Stop) return false;
      if (single_record && state == State::Records) state = State::Done;  // the chunk asked for was refused
    }
    return false;
  }

  // One top-level record: read, checked, and handed on (or skipped).
  Step next_top_level(LinearRecord& out) {
    std::uint8_t op = 0;
    std::uint64_t len = 0;
    if (!read_prefix(op, len)) return Step::Stop;
    const std::uint64_t at = pos;
    const auto o = static_cast<Opcode>(op);
    const bool wanted = o == Opcode::Header || o == Opcode::Schema || o == Opcode::Channel || o == Opcode::Message ||
                        o == Opcode::Chunk || o == Opcode::Attachment || o == Opcode::Metadata ||
                        o == Opcode::DataEnd || o == Opcode::Footer;
    if (single_record && o != Opcode::Chunk) {
      state = State::Done;
      problem(at,
              {StatusCode::InvalidRecord, fmt::format("{}: a chunk index points here, at no chunk", where(at, op))});
      return Step::Stop;
    }
    if (!wanted && !(opt.validate_crcs && !data_end)) {  // skip without reading
      pos += kRecordPrefix + len;
      return Step::Skip;
    }
    const std::uint32_t crc_before = data_crc;
    if (!read_content(op, len)) return Step::Stop;
    pos += kRecordPrefix + len;
    out = LinearRecord{};
    out.opcode = op;
    out.offset = at;
    return dispatch(o, at, crc_before, out);
  }

  Step dispatch(Opcode o, std::uint64_t at, std::uint32_t crc_before, LinearRecord& out) {
    const auto w = [this, at, op = static_cast<std::uint8_t>(o)] { return where(at, op); };
    switch (o) {
      case Opcode::Header:
        if (Status s = wire::parse_lazy(rec, header, w); !s.ok()) return fatal(std::move(s)) ? Step::Skip : Step::Stop;
        out.kind = LinearRecord::Kind::Header;
        out.header = &header;
        return Step::Emit;
      case Opcode::Schema: return on_schema(rec, w, at, false, out);
      case Opcode::Channel: return on_channel(rec, w, at, false, out);
      case Opcode::Message:
        if (message(rec, w, at, out)) return Step::Emit;
        return state == State::Done ? Step::Stop : Step::Skip;
      case Opcode::Chunk:
        if (!open_chunk(at, w())) return state == State::Done ? Step::Stop : Step::Skip;
        out.kind = LinearRecord::Kind::ChunkBegin;
        out.chunk = &chunk;
        return Step::Emit;
      case Opcode::Attachment: return on_attachment(w, at, out);
      case Opcode::Metadata:
        if (Status s = wire::parse_lazy(rec, metadata, w); !s.ok())
          return problem(at, std::move(s)) ? Step::Skip : Step::Stop;
        out.kind = LinearRecord::Kind::Metadata;
        out.metadata = &metadata;
        return Step::Emit;
      case Opcode::DataEnd: return on_data_end(w, at, crc_before, out);
      case Opcode::Footer:
        footer = true;
        state = State::Done;
        out.kind = LinearRecord::Kind::Footer;
        return Step::Emit;
      default: return Step::Skip;  // index and summary records, unknown opcodes: skipped (read only for the CRC)
    }
  }

  // Where a definition from the file disagrees with one given by know() (the
  // summary's, under its own CRC), the known one is used and the difference noted.
  template <class R, class W>
  Step on_definition(std::map<std::uint16_t, R>& slots, const std::map<std::uint16_t, R>& known, R parsed, const W& w,
                     std::uint64_t at, const char* what, LinearRecord& out, const R*& field, LinearRecord::Kind kind) {
    auto k = known.find(parsed.id);
    if (k != known.end() && !(k->second == parsed)) {
      problem(at, {StatusCode::InvalidRecord, fmt::format("{}: {} {} differs from the summary's copy ('{}' here, '{}' "
                                                          "there): the summary's is used",
                                                          w(), what, parsed.id, label(parsed), label(k->second))});
      parsed = k->second;
    }
    auto& slot = slots[parsed.id];
    slot = std::move(parsed);
    out.kind = kind;
    out.in_chunk = state == State::InChunk;
    field = &slot;
    return Step::Emit;
  }
  static const std::string& label(const Schema& s) { return s.name; }
  static const std::string& label(const Channel& c) { return c.topic; }

  template <class W>
  Step on_schema(std::span<const std::uint8_t> content, const W& w, std::uint64_t at, bool in_chunk,
                 LinearRecord& out) {
    Schema sc;
    if (Status s = wire::parse_lazy(content, sc, w); !s.ok()) {
      if (in_chunk) {
        end_chunk_with(std::move(s));
        return Step::Skip;
      }
      return problem(at, std::move(s)) ? Step::Skip : Step::Stop;
    }
    if (sc.id == 0) return Step::Skip;  // invalid by the spec: ignored
    return on_definition(schemas, known_schemas, std::move(sc), w, at, "schema", out, out.schema,
                         LinearRecord::Kind::Schema);
  }

  template <class W>
  Step on_channel(std::span<const std::uint8_t> content, const W& w, std::uint64_t at, bool in_chunk,
                  LinearRecord& out) {
    Channel ch;
    if (Status s = wire::parse_lazy(content, ch, w); !s.ok()) {
      if (in_chunk) {
        end_chunk_with(std::move(s));
        return Step::Skip;
      }
      return problem(at, std::move(s)) ? Step::Skip : Step::Stop;
    }
    return on_definition(channels, known_channels, std::move(ch), w, at, "channel", out, out.channel,
                         LinearRecord::Kind::Channel);
  }

  template <class W>
  Step on_attachment(const W& w, std::uint64_t at, LinearRecord& out) {
    Attachment a;
    if (Status s = wire::parse_lazy(rec, a, w); !s.ok()) return problem(at, std::move(s)) ? Step::Skip : Step::Stop;
    if (opt.validate_crcs && a.crc != 0) {
      const std::uint32_t got = crc32(std::span(rec).first(rec.size() - 4));
      if (got != a.crc) {
        Status bad{StatusCode::CrcMismatch, fmt::format("{}: CRC 0x{:08x} != stored 0x{:08x}", w(), got, a.crc)};
        return problem(at, std::move(bad)) ? Step::Skip : Step::Stop;
      }
    }
    out.kind = LinearRecord::Kind::Attachment;
    out.attachment = a;
    return Step::Emit;
  }

  template <class W>
  Step on_data_end(const W& w, std::uint64_t at, std::uint32_t crc_before, LinearRecord& out) {
    DataEnd de;
    data_end = true;
    state = State::Done;
    if (Status s = wire::parse_lazy(rec, de, w); !s.ok()) {
      problem(at, std::move(s));
      return Step::Stop;
    }
    if (opt.validate_crcs && !crc_gap && de.data_section_crc != 0 && de.data_section_crc != crc_before) {
      problem(at, {StatusCode::CrcMismatch, fmt::format("{}: data section CRC 0x{:08x} != stored 0x{:08x}", w(),
                                                        crc_before, de.data_section_crc)});
      if (!opt.recover) return Step::Stop;
    }
    out.kind = LinearRecord::Kind::DataEnd;
    return Step::Emit;
  }

  // Reading starts over at `offset` for the one chunk there (recovery through the summary).
  bool read_chunk_at(std::uint64_t offset) {
    if (state == State::Start && !read_start()) return false;
    pos = offset;
    state = State::Records;
    status = {};
    single_record = true;
    crc_gap = true;  // bytes were skipped: the data section CRC cannot be checked
    return true;
  }

  // A Message record's content (top level or inside a chunk). False when it is
  // skipped (recovery) or fatal (state Done).
  template <class W>
  bool message(std::span<const std::uint8_t> content, const W& w, std::uint64_t at, LinearRecord& out) {
    Message m;
    if (Status s = wire::parse_lazy(content, m, w); !s.ok()) return problem(at, std::move(s)) && false;
    auto it = channels.find(m.channel_id);
    if (it == channels.end()) {
      problem(at,
              {StatusCode::InvalidRecord,
               fmt::format("{}: refers to channel {}, which no Channel record defined before it", w(), m.channel_id)});
      return false;
    }
    out = LinearRecord{};
    out.kind = LinearRecord::Kind::Message;
    out.opcode = static_cast<std::uint8_t>(Opcode::Message);
    out.offset = at;
    out.in_chunk = state == State::InChunk;
    out.message = m;
    out.channel = &it->second;
    auto sc = schemas.find(it->second.schema_id);
    out.schema = sc == schemas.end() ? nullptr : &sc->second;
    return true;
  }

  bool open_chunk(std::uint64_t at, const std::string& w) {
    if (Status s = parse(rec, chunk, w); !s.ok()) return problem(at, std::move(s), true) && false;
    if (Status s =
            decompress(chunk.compression, chunk.records, chunk.uncompressed_size, opt.max_record_bytes, chunk_buf, w);
        !s.ok()) {
      if (s.code == StatusCode::LimitExceeded && !opt.recover) return fatal(std::move(s));
      return problem(at, std::move(s), true) && false;
    }
    if (opt.validate_crcs && chunk.uncompressed_crc != 0) {
      const std::uint32_t got = crc32(chunk_buf);
      if (got != chunk.uncompressed_crc) {
        return problem(at,
                       {StatusCode::CrcMismatch, fmt::format("{}: CRC of the uncompressed records 0x{:08x} != "
                                                             "stored 0x{:08x}",
                                                             w, got, chunk.uncompressed_crc)},
                       true) &&
               false;
      }
    }
    chunk_offset = at;
    chunk_pos = 0;
    state = State::InChunk;
    return true;
  }

  // Next record inside the open chunk; false when the chunk is done (state back to Records).
  bool next_in_chunk(LinearRecord& out) {
    while (chunk_pos < chunk_buf.size()) {
      const std::size_t inner = chunk_pos;
      const std::size_t left = chunk_buf.size() - chunk_pos;
      if (left < kRecordPrefix) {
        return end_chunk_with(
            {StatusCode::InvalidRecord, fmt::format("{}: chunk at byte {} ends inside a record prefix at its byte {}",
                                                    src.name(), chunk_offset, inner)});
      }
      const std::uint8_t op = chunk_buf[inner];
      std::uint64_t len;
      std::memcpy(&len, chunk_buf.data() + inner + 1, 8);
      if (len > left - kRecordPrefix) {
        return end_chunk_with(
            {StatusCode::InvalidRecord, fmt::format("{} claims {} bytes but the chunk has {} after it",
                                                    where_in_chunk(inner, op), len, left - kRecordPrefix)});
      }
      chunk_pos += kRecordPrefix + static_cast<std::size_t>(len);
      const auto content = std::span<const std::uint8_t>(chunk_buf).subspan(inner + kRecordPrefix, len);
      const auto w = [this, inner, op] { return where_in_chunk(inner, op); };
      switch (static_cast<Opcode>(op)) {
        case Opcode::Schema:
        case Opcode::Channel: {
          out = LinearRecord{};
          out.opcode = op;
          out.offset = chunk_offset;
          const Step step = static_cast<Opcode>(op) == Opcode::Schema ? on_schema(content, w, chunk_offset, true, out)
                                                                      : on_channel(content, w, chunk_offset, true, out);
          if (step == Step::Emit) return true;
          if (state != State::InChunk) return false;  // the chunk was given up
          continue;
        }
        case Opcode::Message:
          if (message(content, w, chunk_offset, out)) return true;
          if (state == State::Done) return false;
          continue;
        default: continue;  // anything else inside a chunk is skipped
      }
    }
    state = State::Records;
    return false;
  }

  bool end_chunk_with(Status s) {
    state = State::Records;
    problem(chunk_offset, std::move(s), true);
    return false;
  }
};

LinearReader::LinearReader(Readable& source, LinearReaderOptions options)
    : impl_(std::make_unique<Impl>(source, options)) {}
LinearReader::~LinearReader() = default;

bool LinearReader::next(LinearRecord& out) {
  // Headers are consumed silently after the first: only the first record may be one.
  return impl_->next(out);
}
const Status& LinearReader::status() const { return impl_->status; }
const std::vector<ReadProblem>& LinearReader::problems() const { return impl_->problems; }
std::uint64_t LinearReader::position() const { return impl_->pos; }
const std::map<SchemaId, Schema>& LinearReader::schemas() const { return impl_->schemas; }
const std::map<ChannelId, Channel>& LinearReader::channels() const { return impl_->channels; }
bool LinearReader::data_end_seen() const { return impl_->data_end; }
void LinearReader::know(const std::map<SchemaId, Schema>& schemas, const std::map<ChannelId, Channel>& channels) {
  impl_->known_schemas = schemas;
  impl_->known_channels = channels;
  for (const auto& [id, s] : schemas) impl_->schemas.emplace(id, s);
  for (const auto& [id, c] : channels) impl_->channels.emplace(id, c);
}
bool LinearReader::read_chunk_at(std::uint64_t offset) { return impl_->read_chunk_at(offset); }
bool LinearReader::footer_seen() const { return impl_->footer; }

}  // namespace tinyline::bag
