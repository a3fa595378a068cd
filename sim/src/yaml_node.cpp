// SPDX-License-Identifier: Apache-2.0
#include <sim/yaml_node.hpp>

#include <cmath>

#include <tinyline/common/files.hpp>

namespace tinyline::sim {

namespace {

std::string child_path(const std::string& parent, std::string_view key) {
  if (parent.empty()) return std::string(key);
  return parent + "." + std::string(key);
}

// Edit distance, for "did you mean" on unknown keys.
std::size_t distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

}  // namespace

YamlNode YamlNode::load_file(const std::string& path, std::string_view what) {
  std::string text;
  try {
    text = files::read_text(path, what, kMaxConfigFileBytes);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, 0, "", e.what());
  }
  return load_string(text, path);
}

YamlNode YamlNode::load_string(const std::string& text, const std::string& source_name) {
  try {
    return YamlNode(YAML::Load(text), source_name, "");
  } catch (const YAML::ParserException& e) {
    throw ConfigError(source_name, e.mark.line + 1, e.mark.column + 1, "", "YAML syntax error: " + e.msg);
  }
}

int YamlNode::line() const {
  if (!node_) return 0;
  const auto m = node_.Mark();
  return m.line >= 0 ? m.line + 1 : 0;
}

void YamlNode::fail(const std::string& what) const {
  int line = 0, col = 0;
  if (node_) {
    const auto m = node_.Mark();
    if (m.line >= 0) {
      line = m.line + 1;
      col = m.column + 1;
    }
  }
  throw ConfigError(file_, line, col, path_, what);
}

void YamlNode::require_map() const {
  if (!node_.IsMap()) fail("expected a mapping of keys to values");
}

bool YamlNode::has(std::string_view key) const { return node_.IsMap() && node_[std::string(key)].IsDefined(); }

std::optional<YamlNode> YamlNode::find(std::string_view key) const {
  if (!node_.IsMap()) fail("expected a mapping of keys to values");
  YAML::Node c = node_[std::string(key)];
  if (!c.IsDefined()) return std::nullopt;
  return YamlNode(c, file_, child_path(path_, key));
}

YamlNode YamlNode::at(std::string_view key) const {
  auto c = find(key);
  if (!c) {
    YamlNode(node_, file_, child_path(path_, key)).fail("required field is missing");
  }
  return *c;
}

YamlNode YamlNode::operator[](std::size_t i) const {
  if (!node_.IsSequence()) fail("expected a list");
  if (i >= node_.size()) fail("index " + std::to_string(i) + " out of range");
  return YamlNode(node_[i], file_, path_ + "[" + std::to_string(i) + "]");
}

std::vector<YamlNode> YamlNode::items() const {
  if (is_null()) return {};
  if (!node_.IsSequence()) fail("expected a list");
  std::vector<YamlNode> out;
  out.reserve(node_.size());
  for (std::size_t i = 0; i < node_.size(); ++i)
    out.emplace_back(node_[i], file_, path_ + "[" + std::to_string(i) + "]");
  return out;
}

std::vector<std::string> YamlNode::keys() const {
  std::vector<std::string> out;
  if (!node_.IsMap()) return out;
  for (auto it = node_.begin(); it != node_.end(); ++it) out.push_back(it->first.Scalar());
  return out;
}

void YamlNode::check_keys(std::initializer_list<std::string_view> allowed) const {
  check_keys(std::vector<std::string>(allowed.begin(), allowed.end()));
}

void YamlNode::check_keys(const std::vector<std::string>& allowed) const {
  require_map();
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string k = it->first.Scalar();
    bool ok = false;
    for (const auto& a : allowed) ok = ok || (a == k);
    if (ok) continue;
    std::string hint;
    std::size_t best = 3;
    for (const auto& a : allowed) {
      const std::size_t d = distance(k, a);
      if (d < best) {
        best = d;
        hint = a;
      }
    }
    std::string what = "unknown key '" + k + "'";
    if (!hint.empty()) what += " (did you mean '" + hint + "'?)";
    YamlNode(it->first, file_, child_path(path_, k)).fail(what);
  }
}

double YamlNode::as_double() const {
  if (!node_.IsScalar()) fail("expected a number");
  double v = 0.0;
  try {
    v = node_.as<double>();
  } catch (const YAML::Exception&) {
    fail("expected a number, got '" + node_.Scalar() + "'");
  }
  if (!std::isfinite(v)) fail("must be a finite number (got '" + node_.Scalar() + "')");
  return v;
}

int YamlNode::as_int() const {
  if (!node_.IsScalar()) fail("expected an integer");
  try {
    return node_.as<int>();
  } catch (const YAML::Exception&) {
    fail("expected an integer, got '" + node_.Scalar() + "'");
  }
}

bool YamlNode::as_bool() const {
  if (!node_.IsScalar()) fail("expected true or false");
  try {
    return node_.as<bool>();
  } catch (const YAML::Exception&) {
    fail("expected true or false, got '" + node_.Scalar() + "'");
  }
}

std::string YamlNode::as_string() const {
  if (!node_.IsScalar()) fail("expected a string");
  return node_.Scalar();
}

std::vector<double> YamlNode::as_doubles(std::size_t expected_size) const {
  if (!node_.IsSequence()) fail("expected a list of numbers");
  if (expected_size != 0 && node_.size() != expected_size) {
    fail("expected " + std::to_string(expected_size) + " numbers, got " + std::to_string(node_.size()));
  }
  std::vector<double> out;
  for (const auto& e : items()) out.push_back(e.as_double());
  return out;
}

Eigen::Vector3d YamlNode::as_vec3() const {
  const auto v = as_doubles(3);
  return {v[0], v[1], v[2]};
}

Eigen::Vector2d YamlNode::as_vec2() const {
  const auto v = as_doubles(2);
  return {v[0], v[1]};
}

double YamlNode::get_double(std::string_view key, double fallback) const {
  auto c = find(key);
  return c ? c->as_double() : fallback;
}
int YamlNode::get_int(std::string_view key, int fallback) const {
  auto c = find(key);
  return c ? c->as_int() : fallback;
}
bool YamlNode::get_bool(std::string_view key, bool fallback) const {
  auto c = find(key);
  return c ? c->as_bool() : fallback;
}
std::string YamlNode::get_string(std::string_view key, const std::string& fallback) const {
  auto c = find(key);
  return c ? c->as_string() : fallback;
}

double YamlNode::positive(std::string_view key) const {
  const YamlNode c = at(key);
  const double v = c.as_double();
  if (!(v > 0.0)) c.fail("must be > 0 (got " + c.raw().Scalar() + ")");
  return v;
}

double YamlNode::positive(std::string_view key, double fallback) const { return has(key) ? positive(key) : fallback; }

double YamlNode::non_negative(std::string_view key, double fallback) const {
  auto c = find(key);
  if (!c) return fallback;
  const double v = c->as_double();
  if (v < 0.0) c->fail("must be >= 0 (got " + c->raw().Scalar() + ")");
  return v;
}

double YamlNode::in_range(std::string_view key, double fallback, double lo, double hi) const {
  auto c = find(key);
  if (!c) return fallback;
  const double v = c->as_double();
  if (v < lo || v > hi) {
    std::ostringstream s;
    s << "must be in [" << lo << ", " << hi << "] (got " << c->raw().Scalar() << ")";
    c->fail(s.str());
  }
  return v;
}

Eigen::Isometry3d YamlNode::as_pose() const {
  require_map();
  check_keys({"xyz", "rpy_deg", "quat_xyzw"});
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (auto xyz = find("xyz")) T.translation() = xyz->as_vec3();
  if (has("rpy_deg") && has("quat_xyzw")) fail("give either rpy_deg or quat_xyzw, not both");
  if (auto rpy = find("rpy_deg")) {
    const Eigen::Vector3d r = rpy->as_vec3() * (M_PI / 180.0);
    T.linear() =
        (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
  } else if (auto q = find("quat_xyzw")) {
    const auto v = q->as_doubles(4);
    Eigen::Quaterniond quat(v[3], v[0], v[1], v[2]);
    if (quat.norm() < 1e-9) q->fail("quaternion has zero norm");
    T.linear() = quat.normalized().toRotationMatrix();
  }
  return T;
}

}  // namespace tinyline::sim
