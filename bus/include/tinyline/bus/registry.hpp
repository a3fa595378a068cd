// SPDX-License-Identifier: Apache-2.0
// Node types by name, so launch files and `tinyline run` can create them.
// Each package with nodes exposes `void register_nodes(bus::NodeRegistry&)`;
// the tinyline tools call them all. A robot stack embedding one node can call
// just that package's function, or construct the class directly.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/bus/node.hpp>

namespace tinyline::bus {

struct NodeTypeInfo {
  std::string pkg;          ///< e.g. "laser_clustering"
  std::string type;         ///< the launch file's `exec`, e.g. "line_clusterer"
  std::string description;  ///< one line for `tinyline nodes`
  std::function<std::shared_ptr<Node>(NodeOptions)> factory;

  std::string full_name() const { return pkg + "/" + type; }
};

class NodeRegistry {
 public:
  /// Throws std::invalid_argument on a duplicate pkg/type.
  void add(NodeTypeInfo info);

  template <class N>
  void add(std::string pkg, std::string type, std::string description) {
    add(NodeTypeInfo{std::move(pkg), std::move(type), std::move(description),
                     [](NodeOptions o) -> std::shared_ptr<Node> { return std::make_shared<N>(std::move(o)); }});
  }

  const NodeTypeInfo* find(std::string_view pkg, std::string_view type) const;
  std::vector<const NodeTypeInfo*> all() const;

  /// Builds a node of a registered type: sets its type name, constructs it,
  /// and checks that every parameter override matched a declaration.
  /// Throws ParamError / std::invalid_argument with the reason.
  std::shared_ptr<Node> create(std::string_view pkg, std::string_view type, NodeOptions options) const;

 private:
  std::vector<NodeTypeInfo> types_;
};

}  // namespace tinyline::bus
