// SPDX-License-Identifier: Apache-2.0
// Records the largest single allocation made through operator new while a
// Tracking object lives (for "no unbounded allocation" checks). The
// replacement operators live in alloc_tracker.cpp, linked into the test.
#pragma once

#include <cstddef>

namespace tinyline::bag::testing {

void start_tracking();
void stop_tracking();
std::size_t largest_allocation();

struct Tracking {
  Tracking() { start_tracking(); }
  ~Tracking() { stop_tracking(); }
  Tracking(const Tracking&) = delete;
  Tracking& operator=(const Tracking&) = delete;
  std::size_t largest() const { return largest_allocation(); }
};

}  // namespace tinyline::bag::testing
