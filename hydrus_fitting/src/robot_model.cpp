// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/robot_model.hpp"

#include "hydrus_fitting/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <tinyline/common/files.hpp>

namespace tinyline::hydrus_fitting {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
}

RobotModelError::RobotModelError(std::string file, int line, std::string field, const std::string& reason)
    : std::runtime_error(line > 0 ? fmt::format("{}:{}: {}: {}", file, line, field, reason)
                                  : fmt::format("{}: {}: {}", file, field, reason)),
      file_(std::move(file)),
      line_(line),
      field_(std::move(field)) {}

// ---------------------------------------------------------------------------- SensorSpec

double SensorSpec::fov_half_angle_rad() const { return std::atan(0.5 * sensor_length_mm / focal_mm); }

Eigen::Isometry2d SensorSpec::T_link_sensor() const {
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.translation() = position_m;
  T.linear() = Eigen::Rotation2Dd(yaw_rad).toRotationMatrix();
  return T;
}

Eigen::Vector2d SensorSpec::ray(double pixel_angle_rad) const {
  // LineScan: a pixel looks along (x, z) = (sin a, cos a), z forward, x along the line.
  const double lateral = std::sin(pixel_angle_rad);
  return {std::cos(pixel_angle_rad), line_axis_left ? lateral : -lateral};
}

// ---------------------------------------------------------------------------- YAML

namespace {

/// yaml-cpp access with file:line:field errors.
struct Reader {
  std::string file;

  [[noreturn]] void fail(const YAML::Node& n, const std::string& field, const std::string& reason) const {
    const int line = n.IsDefined() ? n.Mark().line + 1 : 0;
    throw RobotModelError(file, line, field, reason);
  }
  void check_keys(const YAML::Node& n, const std::string& where, std::initializer_list<const char*> allowed) const {
    if (!n.IsMap()) fail(n, where, "expected a mapping");
    for (const auto& kv : n) {
      const auto key = kv.first.as<std::string>();
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return key == a; })) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(kv.first, where + "." + key, "unknown key (allowed: " + list + ")");
      }
    }
  }
  double number(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) fail(n, field, "expected a number");
    try {
      const double v = n.as<double>();
      if (!std::isfinite(v)) fail(n, field, "must be finite");
      return v;
    } catch (const YAML::Exception&) {
      fail(n, field, "expected a number, got '" + n.Scalar() + "'");
    }
  }
  std::string text(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar() || n.Scalar().empty()) fail(n, field, "expected a non-empty string");
    return n.Scalar();
  }
  std::vector<double> numbers(const YAML::Node& n, const std::string& field, std::size_t count) const {
    if (!n.IsSequence() || n.size() != count) fail(n, field, fmt::format("expected a list of {} numbers", count));
    std::vector<double> v;
    for (std::size_t i = 0; i < count; ++i) v.push_back(number(n[i], fmt::format("{}[{}]", field, i)));
    return v;
  }
};

}  // namespace

RobotModel RobotModel::load(const std::string& path) {
  std::string text;
  try {
    text = files::read_text(path, "robot description", kMaxRobotDescriptionBytes);
  } catch (const files::FileError& e) {
    throw RobotModelError(path, 0, "file", e.what());
  }
  return parse(text, path);
}

namespace {

/// links[i].joint: its name (unique among every name) and optional limits.
void parse_joint(const Reader& r, const YAML::Node& j, const std::string& where, std::set<std::string>& names,
                 LinkSpec& s) {
  r.check_keys(j, where, {"name", "limits_deg"});
  if (!j["name"]) r.fail(j, where + ".name", "missing");
  s.joint = r.text(j["name"], where + ".name");
  if (!names.insert(s.joint).second) r.fail(j["name"], where + ".name", "duplicate name '" + s.joint + "'");
  if (j["limits_deg"]) {
    const auto lim = r.numbers(j["limits_deg"], where + ".limits_deg", 2);
    if (!(lim[0] < lim[1])) r.fail(j["limits_deg"], where + ".limits_deg", "need min < max");
    s.joint_min_rad = lim[0] * kDeg;
    s.joint_max_rad = lim[1] * kDeg;
  }
}

/// links[i]: the first is the base (no joint), every later one hangs on a joint.
LinkSpec parse_link(const Reader& r, const YAML::Node& l, std::size_t i, std::set<std::string>& names) {
  const std::string where = fmt::format("links[{}]", i);
  r.check_keys(l, where, {"name", "length_m", "width_m", "joint"});
  LinkSpec s;
  if (!l["name"]) r.fail(l, where + ".name", "missing");
  s.name = r.text(l["name"], where + ".name");
  if (!names.insert(s.name).second) r.fail(l["name"], where + ".name", "duplicate name '" + s.name + "'");
  if (!l["length_m"]) r.fail(l, where + ".length_m", "missing");
  s.length_m = r.number(l["length_m"], where + ".length_m");
  if (!(s.length_m > 0.0)) r.fail(l["length_m"], where + ".length_m", "must be > 0");
  if (l["width_m"]) {
    s.width_m = r.number(l["width_m"], where + ".width_m");
    if (!(s.width_m >= 0.0)) r.fail(l["width_m"], where + ".width_m", "must be >= 0");
  }
  const YAML::Node j = l["joint"];
  if (i == 0 && j) r.fail(j, where + ".joint", "the first link is the base: it has no joint");
  if (i > 0) {
    if (!j) r.fail(l, where + ".joint", "missing (every link after the first hangs on a joint)");
    parse_joint(r, j, where + ".joint", names, s);
  }
  return s;
}

/// A sensor's optional lens, fan, line axis and range fields.
void parse_sensor_optics(const Reader& r, const YAML::Node& n, const std::string& where, SensorSpec& s) {
  if (n["height_m"]) s.height_m = r.number(n["height_m"], where + ".height_m");
  if (n["focal_mm"]) {
    s.focal_mm = r.number(n["focal_mm"], where + ".focal_mm");
    if (!(s.focal_mm > 0.0)) r.fail(n["focal_mm"], where + ".focal_mm", "must be > 0");
  }
  if (n["sensor_length_mm"]) {
    s.sensor_length_mm = r.number(n["sensor_length_mm"], where + ".sensor_length_mm");
    if (!(s.sensor_length_mm > 0.0)) r.fail(n["sensor_length_mm"], where + ".sensor_length_mm", "must be > 0");
  }
  if (n["fan_half_angle_deg"]) {
    const double f = r.number(n["fan_half_angle_deg"], where + ".fan_half_angle_deg");
    if (!(f > 0.0 && f < 90.0)) r.fail(n["fan_half_angle_deg"], where + ".fan_half_angle_deg", "must be in (0, 90)");
    s.fan_half_angle_rad = f * kDeg;
  }
  if (n["line_axis"]) {
    const std::string a = r.text(n["line_axis"], where + ".line_axis");
    if (a != "left" && a != "right") r.fail(n["line_axis"], where + ".line_axis", "must be 'left' or 'right'");
    s.line_axis_left = (a == "left");
  }
  if (n["range_m"]) {
    const auto rr = r.numbers(n["range_m"], where + ".range_m", 2);
    if (!(rr[0] >= 0.0 && rr[0] < rr[1])) r.fail(n["range_m"], where + ".range_m", "need 0 <= min < max");
    s.min_range_m = rr[0];
    s.max_range_m = rr[1];
  }
}

/// sensors[i]: on a named link, at the first sensor's height (fusion works in one plane).
SensorSpec parse_sensor(const Reader& r, const YAML::Node& n, std::size_t i, std::set<std::string>& names,
                        const std::vector<LinkSpec>& links, const SensorSpec* first) {
  const std::string where = fmt::format("sensors[{}]", i);
  r.check_keys(n, where,
               {"name", "link", "position_m", "yaw_deg", "height_m", "focal_mm", "sensor_length_mm",
                "fan_half_angle_deg", "line_axis", "range_m"});
  SensorSpec s;
  if (!n["name"]) r.fail(n, where + ".name", "missing");
  s.name = r.text(n["name"], where + ".name");
  if (!names.insert(s.name).second) r.fail(n["name"], where + ".name", "duplicate name '" + s.name + "'");
  if (!n["link"]) r.fail(n, where + ".link", "missing");
  const std::string link = r.text(n["link"], where + ".link");
  const auto it = std::find_if(links.begin(), links.end(), [&](const LinkSpec& l) { return l.name == link; });
  if (it == links.end()) r.fail(n["link"], where + ".link", "no link named '" + link + "'");
  s.link = static_cast<int>(it - links.begin());
  if (!n["position_m"]) r.fail(n, where + ".position_m", "missing");
  const auto pos = r.numbers(n["position_m"], where + ".position_m", 2);
  s.position_m = {pos[0], pos[1]};
  if (!n["yaw_deg"]) r.fail(n, where + ".yaw_deg", "missing");
  s.yaw_rad = r.number(n["yaw_deg"], where + ".yaw_deg") * kDeg;
  parse_sensor_optics(r, n, where, s);
  if (first && std::abs(s.height_m - first->height_m) > 1e-3) {
    r.fail(n["height_m"] ? n["height_m"] : n, where + ".height_m",
           fmt::format("{} m differs from the first sensor's {} m: fusion works in one plane, every sensor "
                       "must be at the same height",
                       s.height_m, first->height_m));
  }
  return s;
}

}  // namespace

RobotModel RobotModel::parse(const std::string& yaml_text, const std::string& source_name) {
  const Reader r{source_name};
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw RobotModelError(source_name, e.mark.line + 1, "yaml", e.msg);
  }
  if (!root.IsMap()) throw RobotModelError(source_name, 0, "root", "expected a mapping with name, links, sensors");
  r.check_keys(root, "root", {"name", "links", "sensors"});

  RobotModel m;
  m.name_ = root["name"] ? r.text(root["name"], "name") : "robot";
  std::set<std::string> names;  // links, joints and sensors share one namespace
  const YAML::Node links = root["links"];
  if (!links || !links.IsSequence() || links.size() == 0)
    r.fail(links ? links : root, "links", "expected a non-empty list");
  for (std::size_t i = 0; i < links.size(); ++i) m.links_.push_back(parse_link(r, links[i], i, names));
  const YAML::Node sensors = root["sensors"];
  if (!sensors || !sensors.IsSequence() || sensors.size() == 0)
    r.fail(sensors ? sensors : root, "sensors", "expected a non-empty list");
  for (std::size_t i = 0; i < sensors.size(); ++i)
    m.sensors_.push_back(
        parse_sensor(r, sensors[i], i, names, m.links_, m.sensors_.empty() ? nullptr : &m.sensors_.front()));
  for (std::size_t i = 1; i < m.links_.size(); ++i) m.joints_.push_back(m.links_[i].joint);
  return m;
}

RobotModel::RobotModel(std::string name, std::vector<LinkSpec> links, std::vector<SensorSpec> sensors)
    : name_(std::move(name)), links_(std::move(links)), sensors_(std::move(sensors)) {
  for (std::size_t i = 1; i < links_.size(); ++i) joints_.push_back(links_[i].joint);
  validate();
}

void RobotModel::validate() const {
  auto bad = [](const std::string& what) { throw std::invalid_argument("robot model: " + what); };
  if (links_.empty()) bad("no links");
  if (sensors_.empty()) bad("no sensors");
  std::set<std::string> names;
  for (std::size_t i = 0; i < links_.size(); ++i) {
    const auto& l = links_[i];
    if (!names.insert(l.name).second) bad("duplicate name '" + l.name + "'");
    if (!(l.length_m > 0.0)) bad(fmt::format("link '{}' length_m must be > 0", l.name));
    if (!(l.width_m >= 0.0)) bad(fmt::format("link '{}' width_m must be >= 0", l.name));
    if (i > 0 && l.joint.empty()) bad(fmt::format("link '{}' has no joint", l.name));
    if (i > 0 && !names.insert(l.joint).second) bad("duplicate name '" + l.joint + "'");
  }
  for (const auto& s : sensors_) {
    if (!names.insert(s.name).second) bad("duplicate name '" + s.name + "'");
    if (s.link < 0 || static_cast<std::size_t>(s.link) >= links_.size())
      bad(fmt::format("sensor '{}' is on link {} of {}", s.name, s.link, links_.size()));
    if (!(s.focal_mm > 0.0) || !(s.sensor_length_mm > 0.0)) bad(fmt::format("sensor '{}' lens is invalid", s.name));
    if (!(s.min_range_m >= 0.0 && s.min_range_m < s.max_range_m)) bad(fmt::format("sensor '{}' range", s.name));
    if (std::abs(s.height_m - sensors_.front().height_m) > 1e-3)
      bad(fmt::format("sensor '{}' is not at the first sensor's height", s.name));
  }
}

std::optional<int> RobotModel::sensor_index(std::string_view name) const {
  for (std::size_t i = 0; i < sensors_.size(); ++i)
    if (sensors_[i].name == name) return static_cast<int>(i);
  return std::nullopt;
}

std::optional<int> RobotModel::joint_index(std::string_view name) const {
  for (std::size_t i = 0; i < joints_.size(); ++i)
    if (joints_[i] == name) return static_cast<int>(i);
  return std::nullopt;
}

Kinematics RobotModel::forward(std::span<const double> q) const {
  if (q.size() != joints_.size())
    throw std::invalid_argument(
        fmt::format("forward kinematics of '{}': {} joint angles for {} joints", name_, q.size(), joints_.size()));
  Kinematics k;
  k.T_base_link.reserve(links_.size());
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  k.T_base_link.push_back(T);
  for (std::size_t i = 1; i < links_.size(); ++i) {
    Eigen::Isometry2d step = Eigen::Isometry2d::Identity();
    step.translation() = Eigen::Vector2d(links_[i - 1].length_m, 0.0);
    step.linear() = Eigen::Rotation2Dd(q[i - 1]).toRotationMatrix();
    T = T * step;
    k.T_base_link.push_back(T);
  }
  k.T_base_sensor.reserve(sensors_.size());
  for (const auto& s : sensors_)
    k.T_base_sensor.push_back(k.T_base_link[static_cast<std::size_t>(s.link)] * s.T_link_sensor());
  return k;
}

// ---------------------------------------------------------------------------- joint states

const char* to_string(JointLookupStatus s) {
  switch (s) {
    case JointLookupStatus::kOk: return "ok";
    case JointLookupStatus::kNoData: return "no_joint_state";
    case JointLookupStatus::kStale: return "stale_joint_state";
    case JointLookupStatus::kBeforeHistory: return "before_joint_history";
  }
  return "unknown";
}

common::Status validate(const JointBufferParams& params) { return common::within_table(params); }

JointStateBuffer::JointStateBuffer(std::vector<std::string> joint_names, JointBufferParams params)
    : names_(std::move(joint_names)), params_(params), series_(names_.size()) {
  if (const common::Status v = validate(params_); !v.ok()) throw std::invalid_argument("joint buffer: " + v.message);
}

void JointStateBuffer::clear() {
  for (auto& s : series_) s.clear();
}

JointAddResult JointStateBuffer::add(std::int64_t stamp_ns, std::span<const std::string> names,
                                     std::span<const double> positions) {
  JointAddResult r;
  const std::size_t n = std::min(names.size(), positions.size());
  if (names.size() != positions.size()) {
    r.reason = fmt::format("{} names but {} positions; used the first {}", names.size(), positions.size(), n);
  }
  const auto history_ns = static_cast<std::int64_t>(params_.history_s * 1e9);
  for (std::size_t k = 0; k < n; ++k) {
    const auto it = std::find(names_.begin(), names_.end(), names[k]);
    if (it == names_.end()) {
      ++r.unknown;
      continue;
    }
    if (!std::isfinite(positions[k])) {
      ++r.non_finite;
      continue;
    }
    auto& s = series_[static_cast<std::size_t>(it - names_.begin())];
    // Keep the series sorted; messages normally arrive in order (append).
    auto pos =
        std::upper_bound(s.begin(), s.end(), stamp_ns, [](std::int64_t t, const Sample& x) { return t < x.t_ns; });
    if (pos != s.begin() && std::prev(pos)->t_ns == stamp_ns) {
      std::prev(pos)->q = positions[k];
    } else {
      s.insert(pos, Sample{stamp_ns, positions[k]});
    }
    while (!s.empty() && s.back().t_ns - s.front().t_ns > history_ns) s.pop_front();
    ++r.used;
  }
  if (r.unknown || r.non_finite) {
    if (!r.reason.empty()) r.reason += "; ";
    r.reason += fmt::format("ignored {} unknown joint name(s) and {} non-finite position(s)", r.unknown, r.non_finite);
  }
  return r;
}

JointLookup JointStateBuffer::at(std::int64_t stamp_ns) const {
  JointLookup out;
  out.positions.resize(names_.size());
  const double tol = params_.tolerance_s;
  for (std::size_t j = 0; j < names_.size(); ++j) {
    const auto& s = series_[j];
    if (s.empty()) {
      out.detail = JointLookupStatus::kNoData;
      out.status = common::Status::not_found(fmt::format("no joint state received yet for joint '{}'", names_[j]));
      return out;
    }
    if (stamp_ns >= s.back().t_ns) {
      const double gap = 1e-9 * static_cast<double>(stamp_ns - s.back().t_ns);
      if (gap > tol) {
        out.detail = JointLookupStatus::kStale;
        out.status = {common::StatusCode::OutOfRange,
                      fmt::format("joint '{}': newest state is {:.3f} s older than the scan (tolerance {:.3f} s)",
                                  names_[j], gap, tol)};
        return out;
      }
      out.positions[j] = s.back().q;
      out.max_gap_s = std::max(out.max_gap_s, gap);
    } else if (stamp_ns <= s.front().t_ns) {
      const double gap = 1e-9 * static_cast<double>(s.front().t_ns - stamp_ns);
      if (gap > tol) {
        out.detail = JointLookupStatus::kBeforeHistory;
        out.status = {
            common::StatusCode::OutOfRange,
            fmt::format("joint '{}': the scan is {:.3f} s older than the oldest kept state (tolerance {:.3f} s)",
                        names_[j], gap, tol)};
        return out;
      }
      out.positions[j] = s.front().q;
      out.max_gap_s = std::max(out.max_gap_s, gap);
    } else {
      const auto hi =
          std::upper_bound(s.begin(), s.end(), stamp_ns, [](std::int64_t t, const Sample& x) { return t < x.t_ns; });
      const auto lo = std::prev(hi);
      const double span = static_cast<double>(hi->t_ns - lo->t_ns);
      const double w = static_cast<double>(stamp_ns - lo->t_ns) / span;
      out.positions[j] = (1.0 - w) * lo->q + w * hi->q;
      const double gap = 1e-9 * static_cast<double>(std::min(stamp_ns - lo->t_ns, hi->t_ns - stamp_ns));
      out.max_gap_s = std::max(out.max_gap_s, gap);
    }
  }
  out.detail = JointLookupStatus::kOk;
  out.status = {};
  return out;
}

}  // namespace tinyline::hydrus_fitting
