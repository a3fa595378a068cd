// SPDX-License-Identifier: Apache-2.0
// A bounded multi-producer multi-consumer ring of queued messages (D. Vyukov's
// bounded MPMC queue): each slot carries a sequence number that says whose
// turn it is, so a producer and a consumer meet on one cache line (the slot)
// and never take a lock. The subscription queue is built on it: publishers
// push, the worker running the subscription's group pops, and a keep-last
// publisher that finds the queue full pops the oldest itself (a second
// consumer), which is why the ring is MPMC and not SPSC.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>

#include <tinyline/bus/message_info.hpp>

namespace tinyline::bus::detail {

class MessageRing {
 public:
  /// `capacity` is rounded up to a power of two, at least 2: with a single
  /// slot, "taken by a consumer that is still reading it" and "free for the
  /// next producer" carry the same sequence number, so a producer could
  /// overwrite a message while it is being taken.
  explicit MessageRing(std::size_t capacity)
      : mask_(std::bit_ceil(std::max<std::size_t>(capacity, 2)) - 1), slots_(std::make_unique<Slot[]>(mask_ + 1)) {
    for (std::size_t i = 0; i <= mask_; ++i) slots_[i].seq.store(i, std::memory_order_relaxed);
  }
  MessageRing(const MessageRing&) = delete;
  MessageRing& operator=(const MessageRing&) = delete;

  std::size_t capacity() const { return mask_ + 1; }

  /// Moves `m` in and returns true, or returns false (and leaves `m`) when
  /// the slot at the tail is still taken: the ring is full or a consumer is
  /// between claiming that slot and releasing it.
  bool try_push(QueuedMessage& m, std::uint64_t stamp) {
    std::uint64_t pos = tail_.load(std::memory_order_relaxed);
    Slot* s;
    for (;;) {
      s = &slots_[pos & mask_];
      const std::uint64_t seq = s->seq.load(std::memory_order_acquire);
      const auto diff = static_cast<std::int64_t>(seq - pos);
      if (diff == 0) {
        if (tail_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) break;
      } else if (diff < 0) {
        return false;
      } else {
        pos = tail_.load(std::memory_order_relaxed);
      }
    }
    s->stamp.store(stamp, std::memory_order_relaxed);
    s->m = std::move(m);
    // seq_cst: the publisher reads the executor's sleeper count next, and a
    // worker going to sleep reads this slot after announcing itself (Dekker).
    s->seq.store(pos + 1, std::memory_order_seq_cst);
    return true;
  }

  /// Takes the oldest message; false when empty (or its producer is still
  /// writing it).
  bool try_pop(QueuedMessage* out, std::uint64_t* stamp = nullptr) {
    std::uint64_t pos = head_.load(std::memory_order_relaxed);
    Slot* s;
    for (;;) {
      s = &slots_[pos & mask_];
      const std::uint64_t seq = s->seq.load(std::memory_order_acquire);
      const auto diff = static_cast<std::int64_t>(seq - (pos + 1));
      if (diff == 0) {
        // seq_cst: a reliable publisher announces that it waits, then reads
        // the size; the consumer advances the head, then reads the waiters.
        if (head_.compare_exchange_weak(pos, pos + 1, std::memory_order_seq_cst, std::memory_order_relaxed)) break;
      } else if (diff < 0) {
        return false;
      } else {
        pos = head_.load(std::memory_order_relaxed);
      }
    }
    if (stamp) *stamp = s->stamp.load(std::memory_order_relaxed);
    *out = std::move(s->m);  // leaves the slot's shared_ptr empty
    s->seq.store(pos + mask_ + 1, std::memory_order_release);
    return true;
  }

  /// The stamp of the oldest message if one is ready. Another consumer may
  /// take it before the caller pops: a hint for choosing, not a claim.
  std::optional<std::uint64_t> front_stamp() const {
    const std::uint64_t pos = head_.load(std::memory_order_acquire);
    const Slot& s = slots_[pos & mask_];
    // seq_cst: pairs with the seq_cst store in try_push (a worker about to sleep reads here).
    if (s.seq.load(std::memory_order_seq_cst) != pos + 1) return std::nullopt;
    return s.stamp.load(std::memory_order_relaxed);
  }

  /// True when the ring holds at least `n` messages. Publishers ask this on
  /// every push: the answer comes from a cached head when that already proves
  /// there is room, so a publish does not pull the consumer's head line.
  bool size_reaches(std::size_t n) {
    const std::uint64_t t = tail_.load(std::memory_order_relaxed);
    if (t - cached_head_.load(std::memory_order_relaxed) < n) return false;  // head >= cached head
    const std::uint64_t h = head_.load(std::memory_order_seq_cst);
    cached_head_.store(h, std::memory_order_relaxed);  // any head once read is a lower bound
    return t > h && t - h >= n;
  }

  /// Messages in the ring (exact when nobody pushes or pops meanwhile).
  std::size_t size() const {
    const std::uint64_t h = head_.load(std::memory_order_seq_cst);
    const std::uint64_t t = tail_.load(std::memory_order_seq_cst);
    return t > h ? static_cast<std::size_t>(t - h) : 0;
  }

 private:
  // One cache line per slot: the producer's write and the consumer's read of
  // one message move exactly one line between their cores.
  struct alignas(64) Slot {
    std::atomic<std::uint64_t> seq{0};
    std::atomic<std::uint64_t> stamp{0};  ///< the group's arrival order
    QueuedMessage m;
  };

  const std::size_t mask_;
  const std::unique_ptr<Slot[]> slots_;
  alignas(64) std::atomic<std::uint64_t> head_{0};  // consumers (the worker; a full keep-last publisher)
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // producers
  std::atomic<std::uint64_t> cached_head_{0};       // producers: a head seen earlier
};

}  // namespace tinyline::bus::detail
