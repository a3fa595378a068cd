#include <tinyline/bag/recover.hpp>

#include <map>

#include <fmt/format.h>

namespace tinyline::bag {

Status recover(Readable& in, Writable& out, const RecoverOptions& options, RecoverReport& report) {
  report = {};
  report.input_bytes = in.size();
  LinearReader lr(in, LinearReaderOptions{options.validate_crcs, options.max_record_bytes, true});
  LinearRecord r;
  // The header comes first; without it there is nothing to recover.
  if (!lr.next(r)) return lr.status().ok() ? Status(StatusCode::InvalidRecord, in.name() + ": empty") : lr.status();
  if (r.kind != LinearRecord::Kind::Header) {
    return {StatusCode::InvalidRecord,
            fmt::format("{}: the first record is {}, not a Header", in.name(), opcode_name(r.opcode))};
  }
  WriterOptions wo = options.writer;
  wo.profile = r.header->profile;
  wo.library = r.header->library.empty() ? "recovered by tinyline" : r.header->library + " (recovered by tinyline)";
  Writer w;
  if (Status s = w.open(std::make_unique<WritableRef>(out), wo); !s.ok()) return s;

  std::map<SchemaId, SchemaId> schema_ids;     // input -> output
  std::map<ChannelId, ChannelId> channel_ids;  // input -> output
  auto map_channel = [&](const Channel& in_ch, ChannelId& out_id) -> Status {
    if (auto it = channel_ids.find(in_ch.id); it != channel_ids.end()) {
      out_id = it->second;
      return {};
    }
    Channel c = in_ch;
    if (c.schema_id != 0) {
      auto sit = schema_ids.find(c.schema_id);
      if (sit == schema_ids.end()) {
        auto known = lr.schemas().find(c.schema_id);
        if (known == lr.schemas().end()) {
          c.schema_id = 0;  // its schema never made it: keep the messages, schemaless
        } else {
          Schema s = known->second;
          if (Status st = w.add_schema(s); !st.ok()) return st;
          schema_ids[known->first] = s.id;
          ++report.schemas;
          c.schema_id = s.id;
        }
      } else {
        c.schema_id = sit->second;
      }
    }
    if (Status st = w.add_channel(c); !st.ok()) return st;
    channel_ids[in_ch.id] = c.id;
    ++report.channels;
    out_id = c.id;
    return {};
  };

  while (lr.next(r)) {
    report.bytes_used = lr.position();
    switch (r.kind) {
      case LinearRecord::Kind::Schema: {
        if (schema_ids.count(r.schema->id) != 0) break;
        Schema s = *r.schema;
        if (Status st = w.add_schema(s); !st.ok()) return st;
        schema_ids[r.schema->id] = s.id;
        ++report.schemas;
        break;
      }
      case LinearRecord::Kind::Channel: {
        ChannelId id;
        if (Status st = map_channel(*r.channel, id); !st.ok()) return st;
        break;
      }
      case LinearRecord::Kind::Message: {
        ChannelId id;
        if (Status st = map_channel(*r.channel, id); !st.ok()) return st;
        Message m = r.message;
        m.channel_id = id;
        if (Status st = w.write(m); !st.ok()) return st;
        ++report.messages;
        break;
      }
      case LinearRecord::Kind::ChunkBegin:
        ++report.chunks;
        break;
      case LinearRecord::Kind::Attachment:
        if (Status st = w.write(r.attachment); !st.ok()) return st;
        ++report.attachments;
        break;
      case LinearRecord::Kind::Metadata:
        if (Status st = w.write(*r.metadata); !st.ok()) return st;
        ++report.metadata;
        break;
      case LinearRecord::Kind::DataEnd:
        report.input_complete = true;
        break;
      default:
        break;
    }
  }
  report.problems = lr.problems();
  for (const auto& p : report.problems) report.chunks_skipped += p.chunk_dropped ? 1 : 0;
  if (!lr.status().ok()) {
    // A hard stop (I/O error, a record over the size limit): keep what was read.
    report.problems.push_back(ReadProblem{lr.position(), lr.status()});
  }
  return w.close();
}

Status recover(const std::string& in_path, const std::string& out_path, const RecoverOptions& options,
               RecoverReport& report) {
  FileReadable in;
  if (Status s = in.open(in_path); !s.ok()) return s;
  FileWritable out;
  FileWritableOptions fo;
  fo.inputs = {in_path};  // never the file being recovered
  if (Status s = out.open(out_path, fo); !s.ok()) return s;
  if (Status s = recover(in, out, options, report); !s.ok()) {
    out.abandon();  // an existing output stays as it was
    return s;
  }
  return out.close();
}

}  // namespace tinyline::bag
