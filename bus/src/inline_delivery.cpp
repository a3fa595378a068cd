// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/executor.hpp>

namespace tinyline::bus {

namespace {
thread_local constinit InlineDelivery* tl_inline = nullptr;
}  // namespace

InlineDelivery::InlineDelivery() : previous_(tl_inline) { tl_inline = this; }

InlineDelivery::~InlineDelivery() {
  flush();
  tl_inline = previous_;
}

bool InlineDelivery::defer(CallbackGroup& g) {
  InlineDelivery* d = tl_inline;
  if (d == nullptr) return false;
  for (const auto& p : d->pending_)
    if (p.get() == &g) return true;
  d->pending_.push_back(g.shared_from_this());
  return true;
}

std::size_t InlineDelivery::flush() {
  if (pending_.empty()) return 0;
  std::vector<std::shared_ptr<CallbackGroup>> todo;
  todo.swap(pending_);
  // The callbacks' own publishes wake workers: one level of inline runs.
  tl_inline = previous_;
  std::size_t blocked = 0;
  for (const auto& g : todo) {
    bool stalled = false;
    if (!g->try_run_inline(&stalled)) g->announce();
    if (stalled) ++blocked;
  }
  tl_inline = this;
  todo.clear();
  if (pending_.capacity() == 0) pending_.swap(todo);  // keep the allocation
  return blocked;
}

}  // namespace tinyline::bus
