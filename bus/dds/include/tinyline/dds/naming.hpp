// SPDX-License-Identifier: Apache-2.0
// ROS 2 names on DDS, as rmw_cyclonedds writes them: topic /a/b travels as DDS
// topic "rt/a/b"; type sensor_msgs/msg/LaserScan as
// "sensor_msgs::msg::dds_::LaserScan_".
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include <tinyline/msg/type_support.hpp>

namespace tinyline::dds {

/// "/a/b" -> "rt/a/b". Throws DdsError for a name that is not absolute.
std::string dds_topic_name(std::string_view topic);
/// "rt/a/b" -> "/a/b"; nullopt for DDS topics that are not ROS topics.
std::optional<std::string> ros_topic_name(std::string_view dds_topic);

/// "sensor_msgs::msg::dds_::LaserScan_" -> "sensor_msgs/msg/LaserScan";
/// nullopt for names that do not follow the ROS 2 convention.
std::optional<std::string> ros_type_name(std::string_view dds_type);
/// The type support whose DDS name this is (nullptr if tinyline has no such type).
const msg::TypeSupport* find_type_by_dds_name(std::string_view dds_type);

}  // namespace tinyline::dds
