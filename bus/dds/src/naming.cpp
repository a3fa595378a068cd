// SPDX-License-Identifier: Apache-2.0
#include <tinyline/dds/naming.hpp>

#include <tinyline/dds/settings.hpp>

namespace tinyline::dds {

std::string dds_topic_name(std::string_view topic) {
  if (topic.empty() || topic[0] != '/') {
    throw DdsError("topic '" + std::string(topic) + "' is not an absolute name; cannot name it on DDS");
  }
  return "rt" + std::string(topic);
}

std::optional<std::string> ros_topic_name(std::string_view dds_topic) {
  if (dds_topic.size() < 4 || dds_topic.substr(0, 3) != "rt/") return std::nullopt;
  return std::string(dds_topic.substr(2));
}

std::optional<std::string> ros_type_name(std::string_view dds_type) {
  // pkg::msg::dds_::Type_ (the namespace part may be msg, srv or action)
  const auto dds = dds_type.find("::dds_::");
  if (dds == std::string_view::npos || dds_type.size() < dds + 9 || dds_type.back() != '_') return std::nullopt;
  const auto ns = dds_type.substr(0, dds);
  const auto first = ns.find("::");
  if (first == std::string_view::npos || first == 0) return std::nullopt;
  std::string out(ns.substr(0, first));
  std::string_view rest = ns.substr(first + 2);
  while (!rest.empty()) {
    const auto sep = rest.find("::");
    out += "/" + std::string(rest.substr(0, sep));
    rest = sep == std::string_view::npos ? std::string_view() : rest.substr(sep + 2);
  }
  out += "/" + std::string(dds_type.substr(dds + 8, dds_type.size() - dds - 9));
  return out;
}

const msg::TypeSupport* find_type_by_dds_name(std::string_view dds_type) {
  const auto ros = ros_type_name(dds_type);
  return ros ? msg::find_type_support(*ros) : nullptr;
}

}  // namespace tinyline::dds
