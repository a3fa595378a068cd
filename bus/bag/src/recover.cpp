// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/recover.hpp>

#include <algorithm>
#include <charconv>
#include <cctype>
#include <map>
#include <optional>
#include <set>

#include <fmt/format.h>

#include <tinyline/bus/names.hpp>

namespace tinyline::bag {

namespace {

// ---------------------------------------------------------------------------- what a damaged string looks like

bool valid_utf8(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    const std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    for (std::size_t k = 1; k < n; ++k) {
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 0x2) return false;
    }
    i += n;
  }
  return true;
}

// Text a person or a tool wrote: UTF-8 without control characters.
bool is_text(std::string_view s) {
  for (const char c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) return false;
  }
  return valid_utf8(s);
}

// An encoding or profile name: lower-case letters, digits and '_', '-', '.'.
bool is_identifier(std::string_view s) {
  for (const char c : s) {
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.')) return false;
  }
  return true;
}

bool is_ros2(const Channel& c) { return c.message_encoding == "cdr"; }
bool fits_cdr(const Schema& s) { return s.encoding == "ros2msg" || s.encoding == "ros2idl" || s.encoding == "omgidl"; }

// ---------------------------------------------------------------------------- ros2msg text

bool is_name(std::string_view s) {
  if (s.empty() || !std::isalpha(static_cast<unsigned char>(s[0]))) return false;
  return std::all_of(s.begin(), s.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

// A field type: a primitive, or a message type (Type, pkg/Type, pkg/msg/Type),
// with an optional string bound (<=N) and array suffix ([], [N], [<=N]).
bool is_field_type(std::string_view t) {
  static const std::set<std::string_view> primitives = {"bool",   "byte",  "char",   "float32", "float64",
                                                        "int8",   "uint8", "int16",  "uint16",  "int32",
                                                        "uint32", "int64", "uint64", "string",  "wstring"};
  if (const auto bracket = t.find('['); bracket != std::string_view::npos) {
    if (t.back() != ']') return false;
    t = t.substr(0, bracket);
  }
  if (const auto bound = t.find("<="); bound != std::string_view::npos) t = t.substr(0, bound);
  if (primitives.count(t) != 0) return true;
  // Packages are lower_case; the type starts with a capital.
  std::size_t start = 0;
  while (true) {
    const std::size_t slash = t.find('/', start);
    const std::string_view part =
        t.substr(start, slash == std::string_view::npos ? std::string_view::npos : slash - start);
    if (!is_name(part)) return false;
    if (slash == std::string_view::npos) return std::isupper(static_cast<unsigned char>(part[0])) != 0;
    if (std::any_of(part.begin(), part.end(), [](char c) { return std::isupper(static_cast<unsigned char>(c)); })) {
      return false;
    }
    start = slash + 1;
  }
}

// "pkg/Type" of the message type a field type names, "" for a primitive;
// an unqualified "Type" is in `package` ("builtin_interfaces/msg/Time[3]" ->
// "builtin_interfaces/Time").
std::string message_type_of(std::string_view t, std::string_view package) {
  t = t.substr(0, std::min(t.find('['), t.find("<=")));
  const std::string_view type = t.substr(t.rfind('/') + 1);
  if (type.empty() || !std::isupper(static_cast<unsigned char>(type.front()))) return {};
  const std::string_view pkg = t.find('/') == std::string_view::npos ? package : t.substr(0, t.find('/'));
  return std::string(pkg) + "/" + std::string(type);
}

// A line without its comment and surrounding blanks.
std::string_view strip_line(std::string_view line) {
  const auto hash = line.find('#');
  if (hash != std::string_view::npos && (hash == 0 || line[hash - 1] == ' ' || line[hash - 1] == '\t')) {
    line = line.substr(0, hash);
  }
  const auto first = line.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  return line.substr(first, line.find_last_not_of(" \t\r") - first + 1);
}

// rosidl names: fields are lower_case, constants UPPER_CASE.
bool fits_rosidl(std::string_view name, bool constant) {
  return is_name(name) && std::all_of(name.begin(), name.end(), [constant](char c) {
           return std::isdigit(static_cast<unsigned char>(c)) || c == '_' ||
                  (constant ? std::isupper(static_cast<unsigned char>(c))
                            : std::islower(static_cast<unsigned char>(c)));
         });
}

// A default or constant value a numeric or boolean field cannot hold
// ("float64 w 1*"); other types' values (strings, arrays) are not checked.
bool literal_fits(std::string_view type, std::string_view value) {
  static const std::set<std::string_view> integers = {"byte",   "char",  "int8",   "uint8", "int16",
                                                      "uint16", "int32", "uint32", "int64", "uint64"};
  value = value.substr(0, value.find_last_not_of(" \t") + 1);
  if (type == "bool")
    return value == "true" || value == "false" || value == "True" || value == "False" || value == "1" || value == "0";
  const char* end = value.data() + value.size();
  if (type == "float32" || type == "float64") {
    double v = 0.0;
    const auto r = std::from_chars(value.data(), end, v);
    return r.ec == std::errc() && r.ptr == end;
  }
  if (integers.count(type) != 0) {
    long long v = 0;
    const auto r = std::from_chars(value.data() + (value.rfind('+', 0) == 0 ? 1 : 0), end, v);
    return r.ec == std::errc() && r.ptr == end;
  }
  return true;
}

// Why a line of ros2msg schema text cannot be right, if it cannot: each is a
// comment, a separator (all '='), "MSG: pkg/Type", a field (with its
// default, if any) or a constant.
std::optional<std::string> ros2msg_line_damage(std::string_view raw) {
  const std::string_view line = strip_line(raw);
  const auto bad = [&] { return std::optional<std::string>("'" + std::string(line) + "'"); };
  if (line.empty() || line.find_first_not_of('=') == std::string_view::npos) return std::nullopt;
  if (line.rfind("MSG: ", 0) == 0) return is_field_type(line.substr(5)) ? std::nullopt : bad();
  const std::size_t space = line.find_first_of(" \t");
  if (space == std::string_view::npos || !is_field_type(line.substr(0, space))) return bad();
  std::string_view rest = line.substr(space);
  rest.remove_prefix(std::min(rest.size(), rest.find_first_not_of(" \t")));
  const std::string_view name = rest.substr(0, rest.find_first_of(" \t="));
  std::string_view after = rest.substr(name.size());
  after.remove_prefix(std::min(after.size(), after.find_first_not_of(" \t")));
  const bool constant = !after.empty() && after[0] == '=';
  if (!fits_rosidl(name, constant)) return bad();
  std::string_view value = constant ? after.substr(1) : after;
  value.remove_prefix(std::min(value.size(), value.find_first_not_of(" \t")));
  return value.empty() || literal_fits(line.substr(0, space), value) ? std::nullopt : bad();
}

std::vector<std::string_view> lines_of(std::string_view text) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    out.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

// Every message type a field uses must have its definition in the text
// (after a "MSG: pkg/Type" line), as ROS 2 writes it. `name` is the schema's
// type ("pkg/msg/Type"), whose package unqualified types of its own text use.
std::optional<std::string> missing_definition(const std::vector<std::string_view>& lines, std::string_view name) {
  std::set<std::string> defined;
  for (const auto l : lines) {
    if (l.rfind("MSG: ", 0) == 0) defined.insert(message_type_of(l.substr(5), {}));
  }
  std::string_view package = name.substr(0, name.find('/'));
  for (const auto l : lines) {
    if (l.rfind("MSG: ", 0) == 0) {
      package = l.substr(5, l.find('/') == std::string_view::npos ? 0 : l.find('/') - 5);
      continue;
    }
    if (l.empty() || l[0] == '#' || l[0] == '=') continue;
    const std::string type = message_type_of(l.substr(0, l.find_first_of(" \t")), package);
    if (!type.empty() && defined.count(type) == 0) return "'" + type + "' is used but not defined";
  }
  return std::nullopt;
}

std::optional<std::string> ros2msg_damage(std::string_view text, std::string_view name) {
  if (!valid_utf8(text)) return "its text is not UTF-8";
  for (const char c : text) {
    if (static_cast<unsigned char>(c) < 0x20 && c != '\n' && c != '\t' && c != '\r')
      return "its text has control characters";
  }
  const auto lines = lines_of(text);
  for (const auto l : lines) {
    if (auto why = ros2msg_line_damage(l)) return "its text has a line that is no ros2msg: " + *why;
  }
  if (auto why = missing_definition(lines, name)) return "its text " + *why;
  return std::nullopt;
}

std::optional<std::string> damage_in(const Schema& s) {
  if (s.name.empty() || !is_text(s.name)) return "its name is no text";
  if (!is_identifier(s.encoding)) return "its encoding '" + s.encoding + "' is no encoding name";
  if (s.encoding == "ros2msg" || s.encoding == "ros2idl") {
    // pkg/msg/Type: lower-case package and interface folder, a capitalised type.
    const bool type_name = std::count(s.name.begin(), s.name.end(), '/') == 2 &&
                           s.name.find_first_of("[<") == std::string::npos && is_field_type(s.name);
    if (!type_name) return "'" + s.name + "' is no ROS 2 type name (pkg/msg/Type)";
    if (s.encoding == "ros2msg") return ros2msg_damage(s.data, s.name);
    if (!valid_utf8(s.data)) return "its text is not UTF-8";
  }
  return std::nullopt;
}

std::optional<std::string> damage_in(const Channel& c) {
  if (!is_identifier(c.message_encoding))
    return "its message encoding '" + c.message_encoding + "' is no encoding name";
  if (c.topic.empty() || !is_text(c.topic)) return "its topic is no text";
  if (is_ros2(c)) {
    try {
      bus::validate_name(c.topic, "topic");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    if (c.topic[0] != '/') return "topic '" + c.topic + "' is not absolute";
  }
  for (const auto& [k, v] : c.metadata) {
    if (!is_text(k) || !valid_utf8(v)) return "its metadata is no text";
  }
  return std::nullopt;
}

std::optional<std::string> damage_in(const Metadata& m) {
  if (!is_text(m.name)) return "its name is no text";
  for (const auto& [k, v] : m.metadata) {
    if (!is_text(k) || !valid_utf8(v)) return "its keys or values are no text";
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------- a non-owning source

class ReadableRef final : public Readable {
 public:
  explicit ReadableRef(Readable& r) : r_(r) {}
  std::uint64_t size() const override { return r_.size(); }
  Status read(std::uint64_t offset, std::span<std::uint8_t> out) override { return r_.read(offset, out); }
  const std::string& name() const override { return r_.name(); }

 private:
  Readable& r_;
};

// ---------------------------------------------------------------------------- recovery

// Reads `in` linearly, seeded with what its summary knows (when it has an
// intact one), writes every record that checks out to `out`, then reads the
// chunks the summary indexes that the linear pass missed.
class Recovery {
 public:
  Recovery(Readable& in, Writable& out, const RecoverOptions& options, RecoverReport& report)
      : in_(in),
        out_(out),
        options_(options),
        report_(report),
        lr_(in, LinearReaderOptions{options.validate_crcs, options.max_record_bytes, true}) {}

  Status run() {
    report_ = {};
    report_.input_bytes = in_.size();
    load_summary();
    LinearRecord r;
    if (!lr_.next(r)) {
      // The magic and nothing whole after it (a 9-byte file): not an "empty" bag.
      if (lr_.status().ok()) {
        return {StatusCode::InvalidRecord,
                fmt::format("{}: {} bytes is too short for an MCAP file (no Header record after the magic)", in_.name(),
                            in_.size())};
      }
      return lr_.status();
    }
    if (r.kind != LinearRecord::Kind::Header) {
      return {StatusCode::InvalidRecord,
              fmt::format("{}: the first record is {}, not a Header", in_.name(), opcode_name(r.opcode))};
    }
    header_ = *r.header;
    if (Status s = read_records(); !s.ok()) return s;
    if (Status s = read_missed_chunks(); !s.ok()) return s;
    finish_report();
    if (Status s = ensure_open(); !s.ok()) return s;
    return writer_.close();
  }

 private:
  // The summary, if the file ends with an intact one: its definitions are
  // trusted over the data section's, its chunk indexes find what a damaged
  // record hides from the linear pass.
  void load_summary() {
    Reader r;
    ReaderOptions ro;
    ro.validate_crcs = true;
    ro.max_record_bytes = options_.max_record_bytes;
    if (!r.open(std::make_unique<ReadableRef>(in_), ro).ok() || !r.has_summary()) return;
    summary_ = r.summary();
    lr_.know(summary_->schemas, summary_->channels);
  }

  Status read_records() {
    LinearRecord r;
    while (lr_.next(r)) {
      if (r.kind == LinearRecord::Kind::ChunkBegin) chunks_read_.insert(r.offset);
      report_.bytes_used = lr_.position();
      if (Status s = handle(r); !s.ok()) return s;
    }
    if (!lr_.status().ok()) {
      // A hard stop (I/O error, a record over the size limit): keep what was read.
      note(lr_.position(), lr_.status());
    }
    return {};
  }

  // Chunks the summary indexes that the linear pass did not read (a damaged
  // record before them threw it off), each read on its own.
  Status read_missed_chunks() {
    if (!summary_) return {};
    std::set<std::uint64_t> offsets;
    for (const auto& ci : summary_->chunk_indexes) offsets.insert(ci.chunk_start_offset);
    for (const auto& p : lr_.problems()) {
      if (p.chunk_dropped) chunks_read_.insert(p.offset);  // tried already, and refused
    }
    for (const std::uint64_t at : offsets) {
      if (chunks_read_.count(at) != 0) continue;
      lr_.read_chunk_at(at);
      LinearRecord r;
      while (lr_.next(r)) {
        if (Status s = handle(r); !s.ok()) return s;
      }
      ++report_.chunks_from_index;
    }
    return {};
  }

  Status handle(const LinearRecord& r) {
    switch (r.kind) {
      case LinearRecord::Kind::Schema: (void)schema(*r.schema); return {};
      case LinearRecord::Kind::Channel: (void)channel(*r.channel, r.offset); return {};
      case LinearRecord::Kind::Message: return message(r);
      case LinearRecord::Kind::ChunkBegin: ++report_.chunks; return {};
      case LinearRecord::Kind::Attachment: return attachment(r.attachment);
      case LinearRecord::Kind::Metadata: return metadata(*r.metadata, r.offset);
      case LinearRecord::Kind::DataEnd: report_.input_complete = true; return {};
      default: return {};
    }
  }

  // The writer opens with the first record to write: by then a schema or a
  // channel can vouch for the profile when the header's is damaged.
  Status ensure_open(bool ros2_record = false) {
    if (open_) return {};
    WriterOptions wo = options_.writer;
    wo.profile = profile(ros2_record);
    wo.library = !is_text(header_.library) || header_.library.empty() ? "recovered by tinyline"
                                                                      : header_.library + " (recovered by tinyline)";
    if (Status s = writer_.open(std::make_unique<WritableRef>(out_), wo); !s.ok()) return s;
    open_ = true;
    return {};
  }

  std::string profile(bool ros2_record) {
    const std::string& p = header_.profile;
    if (p.empty() || p == "ros1" || p == "ros2") return p;
    bool cdr = ros2_record;
    if (summary_) {
      for (const auto& [id, c] : summary_->channels) cdr = cdr || is_ros2(c);
    }
    if (is_identifier(p) && !cdr) return p;  // a profile of its own
    const std::string guess = cdr ? "ros2" : "";
    note(8, {StatusCode::InvalidRecord, fmt::format("{}: the header's profile '{}' is not one its channels fit: "
                                                    "written as '{}'",
                                                    in_.name(), p, guess)});
    return guess;
  }

  // The output id of an input schema (written on first use), or nothing when refused.
  std::optional<SchemaId> schema(const Schema& in) {
    if (auto it = schema_ids_.find(in.id); it != schema_ids_.end()) return it->second;
    if (refused_schemas_.count(in.id) != 0) return std::nullopt;
    if (auto why = damage_in(in)) {
      refused_schemas_.insert(in.id);
      note(0, {StatusCode::InvalidRecord, fmt::format("{}: schema {} refused: {}", in_.name(), in.id, *why)});
      return std::nullopt;
    }
    if (!ensure_open(in.encoding.rfind("ros2", 0) == 0).ok()) return std::nullopt;
    Schema s = in;
    if (!writer_.add_schema(s).ok()) return std::nullopt;
    schema_ids_[in.id] = s.id;
    ++report_.schemas;
    return s.id;
  }

  // The output id of an input channel, or nothing when it (or its schema) is refused.
  std::optional<ChannelId> channel(const Channel& in, std::uint64_t at) {
    if (auto it = channel_ids_.find(in.id); it != channel_ids_.end()) return it->second;
    if (refused_channels_.count(in.id) != 0) return std::nullopt;
    Channel c = in;
    std::optional<std::string> why = damage_in(in);
    if (!why && header_.profile == "ros2" && !is_ros2(c)) {
      why = "its message encoding '" + c.message_encoding + "' is not cdr, as a ros2 file's must be";
    }
    if (!why && c.schema_id != 0) {
      auto known = lr_.schemas().find(c.schema_id);
      if (known == lr_.schemas().end() && is_ros2(c)) {
        why =
            fmt::format("its schema {} is nowhere in the file (cdr messages cannot be read without one)", in.schema_id);
      } else if (known == lr_.schemas().end()) {
        c.schema_id = 0;  // its schema never made it: keep the messages, schemaless
      } else if (is_ros2(c) && !fits_cdr(known->second)) {
        why = fmt::format("its schema's encoding '{}' does not describe cdr messages", known->second.encoding);
      } else if (auto id = schema(known->second)) {
        c.schema_id = *id;
      } else {
        why = fmt::format("its schema {} was refused", in.schema_id);
      }
    }
    if (why) {
      refused_channels_.insert(in.id);
      note(at, {StatusCode::InvalidRecord, fmt::format("{}: channel {} refused: {}", in_.name(), in.id, *why)});
      return std::nullopt;
    }
    if (!ensure_open(is_ros2(c)).ok() || !writer_.add_channel(c).ok()) return std::nullopt;
    channel_ids_[in.id] = c.id;
    ++report_.channels;
    return c.id;
  }

  Status message(const LinearRecord& r) {
    // A top-level record (no chunk CRC vouches for it) after a damaged length
    // may be bytes of something else: it must at least fall in the time span
    // the summary gives.
    if (!r.in_chunk && summary_ && summary_->statistics.message_count > 0 &&
        (r.message.log_time < summary_->statistics.message_start_time ||
         r.message.log_time > summary_->statistics.message_end_time)) {
      ++report_.messages_skipped;
      note(r.offset, {StatusCode::InvalidRecord,
                      fmt::format("{}: Message record at byte {}: log time {} is outside "
                                  "the file's [{}, {}]: not trusted",
                                  in_.name(), r.offset, r.message.log_time, summary_->statistics.message_start_time,
                                  summary_->statistics.message_end_time)});
      return {};
    }
    const auto id = channel(*r.channel, r.offset);
    if (!id) {
      ++report_.messages_skipped;
      return {};
    }
    Message m = r.message;
    m.channel_id = *id;
    if (Status st = writer_.write(m); !st.ok()) return st;
    ++report_.messages;
    return {};
  }

  Status attachment(const Attachment& a) {
    if (!is_text(a.name) || !is_text(a.media_type)) {
      note(0, {StatusCode::InvalidRecord,
               fmt::format("{}: attachment refused: its name or media type is no text", in_.name())});
      return {};
    }
    if (Status s = ensure_open(); !s.ok()) return s;
    if (Status st = writer_.write(a); !st.ok()) return st;
    ++report_.attachments;
    return {};
  }

  Status metadata(const Metadata& m, std::uint64_t at) {
    if (auto why = damage_in(m)) {
      note(at, {StatusCode::InvalidRecord, fmt::format("{}: metadata record refused: {}", in_.name(), *why)});
      return {};
    }
    if (Status s = ensure_open(); !s.ok()) return s;
    if (Status st = writer_.write(m); !st.ok()) return st;
    ++report_.metadata;
    return {};
  }

  void note(std::uint64_t offset, Status s) { notes_.push_back(ReadProblem{offset, std::move(s)}); }

  void finish_report() {
    report_.problems = lr_.problems();
    for (const auto& p : report_.problems) report_.chunks_skipped += p.chunk_dropped ? 1 : 0;
    report_.problems.insert(report_.problems.end(), notes_.begin(), notes_.end());
  }

  Readable& in_;
  Writable& out_;
  const RecoverOptions& options_;
  RecoverReport& report_;
  LinearReader lr_;
  Writer writer_;
  bool open_ = false;
  Header header_;
  std::optional<BagSummary> summary_;
  std::set<std::uint64_t> chunks_read_;         // chunk offsets the linear pass read or tried
  std::map<SchemaId, SchemaId> schema_ids_;     // input -> output
  std::map<ChannelId, ChannelId> channel_ids_;  // input -> output
  std::set<SchemaId> refused_schemas_;
  std::set<ChannelId> refused_channels_;
  std::vector<ReadProblem> notes_;  // refusals, in the order met
};

}  // namespace

Status recover(Readable& in, Writable& out, const RecoverOptions& options, RecoverReport& report) {
  return Recovery(in, out, options, report).run();
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
