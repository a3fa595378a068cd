// SPDX-License-Identifier: Apache-2.0
// Observers of the records a log sink is given, beside the sink itself: the
// DDS bridge forwards its process's records to /rosout this way, whatever
// sink the context has.
#pragma once

#include <functional>

#include <tinyline/bus/logging.hpp>

namespace tinyline::bus {

/// Calls `fn` with every record a Logger writes to `sink` from now on (those
/// the sink's level lets through), on the logging thread, after the sink.
/// Returns an id for remove_log_observer().
int add_log_observer(const LogSink* sink, std::function<void(const LogRecord&)> fn);
/// After it returns, the observer is not running and will not run again.
void remove_log_observer(int id);

}  // namespace tinyline::bus
