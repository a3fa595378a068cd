// SPDX-License-Identifier: Apache-2.0
// CSV reader/writer of calibration data sets.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <optional>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <tinyline/common/files.hpp>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_calibration {

using tiny_laser_driver::kPixels;

void CalibrationDataset::add(Readout r, double distance, const std::string& material_name, std::size_t line_no) {
  readouts.push_back(std::move(r));
  distance_m.push_back(distance);
  line.push_back(line_no);
  if (!has_material) {
    material.push_back(-1);
    return;
  }
  auto it = std::find(materials.begin(), materials.end(), material_name);
  if (it == materials.end()) it = materials.insert(materials.end(), material_name);
  material.push_back(static_cast<int>(it - materials.begin()));
}

int CalibrationDataset::extra_index(std::string_view name) const {
  const auto it = std::find(extra_names.begin(), extra_names.end(), name);
  return it == extra_names.end() ? -1 : static_cast<int>(it - extra_names.begin());
}

CalibrationDataset CalibrationDataset::subset(const std::vector<std::size_t>& rows) const {
  CalibrationDataset out;
  out.source = source;
  out.extra_names = extra_names;
  out.has_material = has_material;
  out.materials = materials;
  out.readouts.reserve(rows.size());
  for (std::size_t i : rows) {
    out.readouts.push_back(readouts[i]);
    out.distance_m.push_back(distance_m[i]);
    out.material.push_back(material[i]);
    out.line.push_back(line[i]);
  }
  return out;
}

namespace {

constexpr double kMaxTruthDistanceM = 100.0;

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// Splits one CSV line; a cell may be double-quoted ("" inside is a quote).
// Returns false on an unterminated quote.
bool split(std::string_view line, std::vector<std::string>& cells) {
  cells.clear();
  std::string cur;
  bool quoted = false;
  bool was_quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"') {
        if (i + 1 < line.size() && line[i + 1] == '"') {
          cur += '"';
          ++i;
        } else {
          quoted = false;
        }
      } else {
        cur += c;
      }
    } else if (c == '"' && trim(cur).empty()) {
      quoted = true;
      was_quoted = true;
      cur.clear();
    } else if (c == ',') {
      cells.push_back(was_quoted ? cur : std::string(trim(cur)));
      cur.clear();
      was_quoted = false;
    } else {
      cur += c;
    }
  }
  if (quoted) return false;
  cells.push_back(was_quoted ? cur : std::string(trim(cur)));
  return true;
}

bool parse_double(std::string_view s, double& v) {
  s = trim(s);
  if (s.empty()) return false;
  if (s.front() == '+') s.remove_prefix(1);
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && p == s.data() + s.size();
}

// Where the columns are: the header line's answer.
struct CsvLayout {
  enum Col { kT, kPixel, kPulses, kA, kB, kTemp, kDist, kCount };
  std::vector<std::string> header;
  int col[kCount] = {};
  int material_col = -1;
  std::vector<int> extra_cols;
};

// Numbers of one data line, each failure naming the file, line and column.
class CellReader {
 public:
  CellReader(const CsvLayout& layout, const std::vector<std::string>& cells, const std::string& source,
             std::size_t line)
      : layout_(layout), cells_(cells), source_(source), line_(line) {}
  [[nodiscard]] CalibrationDataError fail(const std::string& what) const {
    return CalibrationDataError(fmt::format("{}:{}: {}", source_, line_, what));
  }
  double number(int c) const {
    double v = 0.0;
    const auto& cell = cells_[static_cast<std::size_t>(c)];
    const auto& name = layout_.header[static_cast<std::size_t>(c)];
    if (!parse_double(cell, v)) throw fail(fmt::format("column '{}': '{}' is not a number", name, cell));
    if (!std::isfinite(v)) throw fail(fmt::format("column '{}': '{}' is not finite", name, cell));
    return v;
  }
  int integer(int c, double lo, double hi) const {
    const double v = number(c);
    if (v != std::floor(v) || v < lo || v > hi) {
      throw fail(fmt::format("column '{}': '{}' is not an integer in [{}, {}]",
                             layout_.header[static_cast<std::size_t>(c)], cells_[static_cast<std::size_t>(c)], lo, hi));
    }
    return static_cast<int>(v);
  }

 private:
  const CsvLayout& layout_;
  const std::vector<std::string>& cells_;
  const std::string& source_;
  std::size_t line_;
};

// The header: every column named once, the required ones present; the rest is
// the material (text) or further numeric covariates.
CsvLayout read_header(const std::vector<std::string>& cells, const std::string& source, std::size_t line_no,
                      CalibrationDataset& data) {
  auto fail = [&](const std::string& what) {
    return CalibrationDataError(fmt::format("{}:{}: {}", source, line_no, what));
  };
  CsvLayout l;
  l.header = cells;
  const auto& header = l.header;
  for (std::size_t i = 0; i < header.size(); ++i) {
    if (header[i].empty()) throw fail(fmt::format("header: column {} has no name", i + 1));
    for (std::size_t j = 0; j < i; ++j) {
      if (header[j] == header[i]) throw fail(fmt::format("header: column '{}' appears twice", header[i]));
    }
  }
  for (int c = 0; c < CsvLayout::kCount; ++c) {
    const auto it = std::find(header.begin(), header.end(), kRequiredCalibrationColumns[c]);
    if (it == header.end()) {
      throw fail(
          fmt::format("missing required column '{}' (header has: {}; required: "
                      "t_s,pixel,pulses,a,b,temperature_c,distance_m)",
                      kRequiredCalibrationColumns[c], fmt::join(header, ",")));
    }
    l.col[c] = static_cast<int>(it - header.begin());
  }
  for (std::size_t i = 0; i < header.size(); ++i) {
    const bool required =
        std::any_of(std::begin(l.col), std::end(l.col), [&](int c) { return c == static_cast<int>(i); });
    if (required) continue;
    if (header[i] == "material") {
      l.material_col = static_cast<int>(i);
    } else {
      l.extra_cols.push_back(static_cast<int>(i));
      data.extra_names.push_back(header[i]);
    }
  }
  data.has_material = l.material_col >= 0;
  return l;
}

void add_row(const CsvLayout& l, const std::vector<std::string>& cells, const std::string& source, std::size_t line_no,
             CalibrationDataset& data) {
  const CellReader cell(l, cells, source, line_no);
  if (cells.size() != l.header.size()) {
    throw cell.fail(fmt::format("expected {} cells (one per header column), found {}", l.header.size(), cells.size()));
  }
  Readout r;
  r.t_s = cell.number(l.col[CsvLayout::kT]);
  r.pixel = cell.integer(l.col[CsvLayout::kPixel], 0, static_cast<double>(kPixels - 1));
  r.pulses = cell.integer(l.col[CsvLayout::kPulses], 1, 1e9);
  r.a = cell.number(l.col[CsvLayout::kA]);
  r.b = cell.number(l.col[CsvLayout::kB]);
  r.temperature_c = cell.number(l.col[CsvLayout::kTemp]);
  const double d = cell.number(l.col[CsvLayout::kDist]);
  if (!(d > 0.0)) throw cell.fail(fmt::format("column 'distance_m': {} is not a positive distance", d));
  // A time-of-flight line sensor reads centimetres to metres: 1e22 m is a broken column, not a target.
  if (d > kMaxTruthDistanceM) {
    throw cell.fail(fmt::format("column 'distance_m': {} m is beyond any target of this sensor (at most {} m)", d,
                                kMaxTruthDistanceM));
  }
  r.extra.reserve(l.extra_cols.size());
  for (int c : l.extra_cols) r.extra.push_back(cell.number(c));
  data.add(std::move(r), d, l.material_col >= 0 ? cells[static_cast<std::size_t>(l.material_col)] : std::string(),
           line_no);
}

}  // namespace

CalibrationDataset parse_calibration_csv(std::string_view text, const std::string& source) {
  CalibrationDataset data;
  data.source = source;
  auto fail = [&](std::size_t line, const std::string& what) -> CalibrationDataError {
    return CalibrationDataError(line ? fmt::format("{}:{}: {}", source, line, what)
                                     : fmt::format("{}: {}", source, what));
  };
  std::optional<CsvLayout> layout;
  std::vector<std::string> cells;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = trim(text.substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    if (line.empty() || line.front() == '#') continue;
    if (line.find('\0') != std::string_view::npos) throw fail(line_no, "binary data (NUL byte): not a CSV file");
    if (!split(line, cells)) throw fail(line_no, "unterminated quoted cell");
    if (!layout) {
      layout = read_header(cells, source, line_no, data);
    } else {
      add_row(*layout, cells, source, line_no, data);
    }
  }
  if (!layout) throw fail(0, "empty file: no header line (expected t_s,pixel,pulses,a,b,temperature_c,distance_m)");
  if (data.empty()) throw fail(0, "no data rows after the header");
  return data;
}

CalibrationDataset read_calibration_csv(const std::string& path) {
  std::string text;
  try {
    text = files::read_text(path, "data file", kMaxCalibrationCsvBytes);
  } catch (const files::FileError& e) {
    throw CalibrationDataError(e.what());
  }
  return parse_calibration_csv(text, path);
}

void write_calibration_csv(const CalibrationDataset& data, std::ostream& out) {
  out << "t_s,pixel,pulses,a,b,temperature_c,distance_m";
  if (data.has_material) out << ",material";
  for (const auto& n : data.extra_names) out << ',' << n;
  out << '\n';
  std::string line;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const Readout& r = data.readouts[i];
    line = fmt::format("{},{},{},{},{},{},{}", r.t_s, r.pixel, r.pulses, r.a, r.b, r.temperature_c, data.distance_m[i]);
    if (data.has_material) {
      const int m = data.material[i];
      line += ',';
      if (m >= 0) line += data.materials[static_cast<std::size_t>(m)];
    }
    for (double v : r.extra) line += fmt::format(",{}", v);
    line += '\n';
    out << line;
  }
}

void write_calibration_csv(const CalibrationDataset& data, const std::string& path) {
  // A temporary name renamed at the end: a full disk or a crash never leaves half a file under `path`.
  try {
    files::AtomicStream out(path, files::named("data file"));
    write_calibration_csv(data, out);
    out.commit();
  } catch (const files::FileError& e) {
    throw CalibrationDataError(e.what());
  }
}

std::vector<int> frame_ids(const CalibrationDataset& data) {
  const int session = data.extra_index("session");
  auto key = [&](const Readout& r) {
    return std::pair<double, double>(session >= 0 ? r.extra[static_cast<std::size_t>(session)] : 0.0, r.t_s);
  };
  std::vector<std::pair<double, double>> times;
  times.reserve(data.size());
  for (const auto& r : data.readouts) times.push_back(key(r));
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  std::vector<int> ids;
  ids.reserve(data.size());
  for (const auto& r : data.readouts) {
    ids.push_back(static_cast<int>(std::lower_bound(times.begin(), times.end(), key(r)) - times.begin()));
  }
  return ids;
}

std::vector<int> target_distance_groups(const CalibrationDataset& data, double bin_m) {
  const auto frames = frame_ids(data);
  const int n_frames = frames.empty() ? 0 : *std::max_element(frames.begin(), frames.end()) + 1;
  std::vector<std::vector<double>> per_frame(static_cast<std::size_t>(n_frames));
  for (std::size_t i = 0; i < data.size(); ++i)
    per_frame[static_cast<std::size_t>(frames[i])].push_back(data.distance_m[i]);
  std::vector<long long> key(static_cast<std::size_t>(n_frames));
  for (std::size_t f = 0; f < per_frame.size(); ++f) {
    auto& v = per_frame[f];
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    key[f] = std::llround(v[v.size() / 2] / bin_m);
  }
  std::vector<long long> keys = key;
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<int> ids;
  ids.reserve(data.size());
  for (int f : frames) {
    ids.push_back(
        static_cast<int>(std::lower_bound(keys.begin(), keys.end(), key[static_cast<std::size_t>(f)]) - keys.begin()));
  }
  return ids;
}

std::vector<Readout> readouts_for_model(const CalibrationDataset& data, const CalibrationModel& model) {
  const auto& names = model.extra_covariates();
  std::vector<int> idx;
  for (const auto& n : names) idx.push_back(data.extra_index(n));
  std::vector<Readout> out = data.readouts;
  for (auto& r : out) {
    std::vector<double> e(names.size(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t k = 0; k < idx.size(); ++k) {
      if (idx[k] >= 0) e[k] = r.extra[static_cast<std::size_t>(idx[k])];
    }
    r.extra = std::move(e);
  }
  return out;
}

}  // namespace tinyline::tiny_laser_calibration
