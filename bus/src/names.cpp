// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/names.hpp>

#include <cctype>
#include <stdexcept>
#include <string>

namespace tinyline::bus {

void validate_name(std::string_view name, std::string_view what) {
  auto bad = [&](const std::string& why) {
    throw std::invalid_argument(std::string(what) + " '" + std::string(name) + "' is invalid: " + why);
  };
  if (name.empty()) bad("empty");
  std::size_t start = 0;
  if (name[0] == '~') {
    if (name.size() > 1 && name[1] != '/') bad("'~' must be followed by '/'");
    start = 1;
  }
  for (std::size_t i = start; i < name.size(); ++i) {
    const char c = name[i];
    if (c == '/') {
      if (i + 1 < name.size() && name[i + 1] == '/') bad("contains '//'");
      continue;
    }
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) {
      bad(std::string("character '") + c + "' is not allowed (letters, digits, '_' and '/')");
    }
    if (std::isdigit(static_cast<unsigned char>(c)) && (i == 0 || name[i - 1] == '/')) {
      bad("a token may not start with a digit");
    }
  }
  if (name.size() > 1 && name.back() == '/') bad("ends with '/'");
}

std::string normalize_namespace(std::string_view ns) {
  std::string s(ns);
  if (s.empty() || s[0] != '/') s.insert(s.begin(), '/');
  while (s.size() > 1 && s.back() == '/') s.pop_back();
  return s;
}

std::string join_namespace(std::string_view outer, std::string_view inner) {
  if (!inner.empty() && inner[0] == '/') return normalize_namespace(inner);
  std::string o = normalize_namespace(outer);
  if (inner.empty()) return o;
  return normalize_namespace((o == "/" ? "" : o) + "/" + std::string(inner));
}

std::string resolve_name(std::string_view name, std::string_view ns, std::string_view node_name) {
  validate_name(name, "name");
  const std::string n = normalize_namespace(ns);
  if (name[0] == '/') return std::string(name);
  const std::string base = n == "/" ? "" : n;
  if (name[0] == '~') {
    std::string rest(name.substr(1));
    return base + "/" + std::string(node_name) + rest;
  }
  return base + "/" + std::string(name);
}

std::string apply_remaps(const std::string& resolved, const std::vector<Remap>& remaps, std::string_view ns,
                         std::string_view node_name) {
  for (const auto& r : remaps) {
    if (resolve_name(r.from, ns, node_name) == resolved) return resolve_name(r.to, ns, node_name);
  }
  return resolved;
}

}  // namespace tinyline::bus
