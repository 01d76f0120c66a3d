// A lock-free ring buffer for one producer thread and one consumer thread: the servo tick
// hands each tick's record to a normal thread through it. The producer never blocks and
// never allocates: when the ring is full its record is dropped (the caller counts it).
// Capacity is fixed at construction (the only allocation).
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace virtmech::drivers {

template <typename T>
class SpscRing {
  static_assert(std::is_trivially_copyable_v<T>, "SpscRing holds trivially copyable records");
  static_assert(std::atomic<std::size_t>::is_always_lock_free, "SpscRing needs lock-free atomics");

 public:
  /// A ring of at least `capacity` slots (rounded up to a power of two), 1 <= capacity <=
  /// 2^24; throws std::invalid_argument otherwise.
  explicit SpscRing(std::size_t capacity) {
    if (capacity < 1 || capacity > (std::size_t{1} << 24)) {
      throw std::invalid_argument("record_capacity: expected 1 to 16777216 records, got " +
                                  std::to_string(capacity));
    }
    std::size_t size = 1;
    while (size < capacity) size <<= 1;
    slots_.reset(new T[size]());
    mask_ = size - 1;
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  std::size_t capacity() const noexcept { return mask_ + 1; }

  /// Producer: the next free slot to fill in place, or nullptr when the ring is full. The
  /// slot is handed over by publish(); a claim without publish is given up by the next claim.
  T* claim() noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_cache_ > mask_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head - tail_cache_ > mask_) return nullptr;
    }
    return &slots_[head & mask_];
  }
  /// Producer: hands the claimed slot to the consumer.
  void publish() noexcept {
    head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }
  /// Producer: claim, copy, publish; false (nothing written) when the ring is full.
  bool push(const T& value) noexcept {
    T* slot = claim();
    if (slot == nullptr) return false;
    *slot = value;
    publish();
    return true;
  }

  /// Consumer: moves up to `max` records, oldest first, into `out`; returns how many.
  std::size_t pop(T* out, std::size_t max) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t head = head_.load(std::memory_order_acquire);
    std::size_t n = head - tail;
    if (n > max) n = max;
    for (std::size_t i = 0; i < n; ++i) out[i] = slots_[(tail + i) & mask_];
    tail_.store(tail + n, std::memory_order_release);
    return n;
  }
  /// Records waiting (either thread; a snapshot).
  std::size_t size() const noexcept {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }

 private:
  // the producer's and the consumer's indices on cache lines of their own
  static constexpr std::size_t kLine = 64;
  std::unique_ptr<T[]> slots_;
  std::size_t mask_ = 0;
  alignas(kLine) std::atomic<std::size_t> head_{0};  // written by the producer
  std::size_t tail_cache_ = 0;                       // the producer's last view of tail_
  alignas(kLine) std::atomic<std::size_t> tail_{0};  // written by the consumer
};

}  // namespace virtmech::drivers
