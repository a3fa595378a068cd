// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/registry.hpp>

#include <algorithm>
#include <stdexcept>

namespace tinyline::bus {

void NodeRegistry::add(NodeTypeInfo info) {
  if (find(info.pkg, info.type) != nullptr) {
    throw std::invalid_argument("node type " + info.full_name() + " is registered twice");
  }
  types_.push_back(std::move(info));
}

const NodeTypeInfo* NodeRegistry::find(std::string_view pkg, std::string_view type) const {
  for (const auto& t : types_)
    if (t.pkg == pkg && t.type == type) return &t;
  return nullptr;
}

std::vector<const NodeTypeInfo*> NodeRegistry::all() const {
  std::vector<const NodeTypeInfo*> out;
  for (const auto& t : types_) out.push_back(&t);
  std::sort(out.begin(), out.end(), [](auto* a, auto* b) { return a->full_name() < b->full_name(); });
  return out;
}

std::shared_ptr<Node> NodeRegistry::create(std::string_view pkg, std::string_view type, NodeOptions options) const {
  const NodeTypeInfo* info = find(pkg, type);
  if (info == nullptr) {
    std::string known;
    for (auto* t : all()) known += (known.empty() ? "" : ", ") + t->full_name();
    throw ParamError(options.where, "unknown node type '" + std::string(pkg) + "/" + std::string(type) +
                                        "' (known: " + (known.empty() ? "none" : known) + ")");
  }
  options.type_name = info->full_name();
  auto node = info->factory(std::move(options));
  node->check_unused_overrides();
  return node;
}

}  // namespace tinyline::bus
