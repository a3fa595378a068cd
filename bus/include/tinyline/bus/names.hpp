// SPDX-License-Identifier: Apache-2.0
// ROS-style names: namespaces, relative and private (~) names, remapping.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace tinyline::bus {

struct Remap {
  std::string from;
  std::string to;
};

/// Throws std::invalid_argument with the reason if `name` is not a valid
/// topic or namespace name (letters, digits, _, / separators, no //).
void validate_name(std::string_view name, std::string_view what);

/// "/a/b" from namespace "/a" and name "b"; "~/x" is private: "/a/node/x";
/// absolute names stay as they are.
std::string resolve_name(std::string_view name, std::string_view ns, std::string_view node_name);

/// Normalises a namespace: leading '/', no trailing '/'; "" -> "/".
std::string normalize_namespace(std::string_view ns);

/// Joins two namespaces ("/a" + "b" -> "/a/b"; an absolute inner one wins).
std::string join_namespace(std::string_view outer, std::string_view inner);

/// Applies the first matching remap: a rule matches when its `from`, resolved
/// in the node's namespace, equals the resolved name.
std::string apply_remaps(const std::string& resolved, const std::vector<Remap>& remaps, std::string_view ns,
                         std::string_view node_name);

}  // namespace tinyline::bus
