// SPDX-License-Identifier: Apache-2.0
// Internal: parameter values from YAML nodes (launch files, -p name:=value).
#pragma once

#include <optional>
#include <string>

#include <yaml-cpp/yaml.h>

#include <tinyline/bus/params.hpp>

namespace tinyline::bus {

/// A scalar or a list of scalars as a typed value; nothing (and why) otherwise.
std::optional<ParamValue> param_from_yaml(const YAML::Node& n, std::string* why);

}  // namespace tinyline::bus
