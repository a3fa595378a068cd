// SPDX-License-Identifier: Apache-2.0
// Generic utility nodes of the `tinyline` package: useful in any graph.
//   tinyline/echo   logs every message of a topic as YAML
//   tinyline/relay  republishes a topic under another name (zero-copy)
//   tinyline/pulse  publishes a counter text at a fixed rate (smoke tests)
//   tf2_ros/static_transform_publisher  one fixed frame on /tf_static, as ROS 2's
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::tools {

void register_nodes(bus::NodeRegistry& r);
/// tf2_ros/static_transform_publisher alone (register_nodes adds it too).
void register_static_transform(bus::NodeRegistry& r);
void register_cloud_stream(bus::NodeRegistry& r);

}  // namespace tinyline::tools
