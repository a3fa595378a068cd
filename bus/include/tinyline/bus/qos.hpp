// SPDX-License-Identifier: Apache-2.0
// Quality of service of a subscription (and what a publisher offers).
//
//  keep_last(N): a queue of N; a new message beyond N drops the oldest and
//                counts the drop. Sensor data, visualisation.
//  reliable(N):  a queue of N; a publisher that finds it full waits up to
//                max_block for room; a timeout is an error reported to the
//                publisher and counted, never a silent loss. Recorders, replay.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>

#include <tinyline/bus/time.hpp>

namespace tinyline::bus {

struct QoS {
  enum class History { KeepLast, Reliable };

  History history = History::KeepLast;
  std::size_t depth = 10;                        ///< queue length (messages)
  Duration max_block = std::chrono::seconds(1);  ///< Reliable: longest wait for room
  bool transient_local = false;                  ///< latched: late subscribers get the last `depth`
  bool best_effort = false;                      ///< across DDS: best-effort delivery

  static QoS keep_last(std::size_t depth = 10) {
    QoS q;
    q.depth = depth;
    return q;
  }
  static QoS reliable(std::size_t depth = 1000, Duration max_block = std::chrono::seconds(1)) {
    QoS q;
    q.history = History::Reliable;
    q.depth = depth;
    q.max_block = max_block;
    return q;
  }
  /// A sensor-data profile: shallow keep-last, best effort across processes.
  static QoS sensor_data(std::size_t depth = 5) {
    QoS q = keep_last(depth);
    q.best_effort = true;
    return q;
  }
  QoS& latched() {
    transient_local = true;
    return *this;
  }

  std::string describe() const;
};

}  // namespace tinyline::bus
