// SPDX-License-Identifier: Apache-2.0
// The RouDi (iceoryx's daemon, `iox-roudi`) of a launch that asks for shared
// memory (`dds: {shared_memory: true}`): the one already running on this
// machine, or one started for the launch and stopped at its end.
#pragma once

#include <memory>
#include <string>

#include "supervisor.hpp"

namespace tinyline::tools {

/// Sets TINYLINE_SHARED_MEMORY=1 for this process and the children it
/// starts from now on. If a RouDi answers on this machine, uses it and
/// returns null (it is not ours to stop); otherwise starts `iox-roudi -c
/// pools` and returns its supervisor once RouDi answers: destroying it stops
/// RouDi, after the processes that use it. Null too when no RouDi can be had
/// (not installed, it did not come up): every process then stays on
/// loopback and says so. Reports each case on stderr with "[launch]".
std::unique_ptr<Supervisor> provide_roudi(const std::string& pools);

}  // namespace tinyline::tools
