// SPDX-License-Identifier: Apache-2.0
#include <thread>
#include <vector>

#include <tinyline/bus/executor.hpp>

namespace tinyline::bus {

void MultiThreadedExecutor::spin() {
  const SpinGuard guard(*this);
  core_->stopping.store(false, std::memory_order_seq_cst);  // see Executor::spin()
  start_pending_nodes();
  std::vector<std::thread> workers;
  for (int i = 1; i < options_.threads; ++i) workers.emplace_back([this] { worker_loop(); });
  worker_loop();
  for (auto& w : workers) w.join();
  stop_.store(false);  // see Executor::spin()
}

}  // namespace tinyline::bus
