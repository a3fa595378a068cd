// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/context.hpp>

namespace tinyline::bus {

Context::Context(ContextOptions options)
    : clock_(options.clock),
      log_sink_(options.log_sink ? std::move(options.log_sink) : std::make_shared<StderrSink>()) {}

std::shared_ptr<Context> Context::create(ContextOptions options) {
  return std::make_shared<Context>(std::move(options));
}

}  // namespace tinyline::bus
