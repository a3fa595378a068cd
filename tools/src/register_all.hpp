// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <tinyline/bus/registry.hpp>

namespace tinyline::tools {

/// Registers the node types of every package in this build (register_all.cpp).
void register_all_nodes(bus::NodeRegistry& r);

}  // namespace tinyline::tools
