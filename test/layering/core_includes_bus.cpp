// SPDX-License-Identifier: Apache-2.0
// Must not compile: a core library reaching for the bus (see CMakeLists.txt).
#include <tiny_laser_driver/protocol.hpp>
#include <tinyline/bus/node.hpp>
