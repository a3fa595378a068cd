// SPDX-License-Identifier: Apache-2.0
// What the executor's files share: which executor runs callbacks on this
// thread (current_executor()).
#pragma once

#include <tinyline/bus/executor.hpp>

namespace tinyline::bus::detail {

extern thread_local constinit const ExecutorCore* tl_core;

/// Names `c` as this thread's executor until the scope ends.
struct CoreScope {
  explicit CoreScope(const ExecutorCore* c) : prev(tl_core) { tl_core = c; }
  ~CoreScope() { tl_core = prev; }
  CoreScope(const CoreScope&) = delete;
  CoreScope& operator=(const CoreScope&) = delete;
  const ExecutorCore* prev;
};

}  // namespace tinyline::bus::detail
