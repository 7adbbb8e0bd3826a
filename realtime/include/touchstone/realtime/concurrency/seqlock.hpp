#pragma once
/// @file
/// A single-writer sequence lock: how the runtime's threads hand small values (a tool pose, the
/// model's K_t and contact frame, a force) to each other without a mutex (the haptic thread
/// never takes one).
///
/// The writer never waits; a reader retries only while a write is in progress, and the haptic
/// thread does not even do that: it calls try_load() once and keeps its previous value when a
/// write was in flight (a fresh copy comes one tick later). The payload is held in atomic words
/// (release stores, acquire loads), so the pattern is race-free in the C++ memory model — and
/// ThreadSanitizer, which cannot see through fences, agrees.

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace touchstone::realtime::concurrency {

template <class T>
class Seqlock {
  static_assert(std::is_trivially_copyable_v<T>, "Seqlock holds trivially copyable values only");
  static constexpr std::size_t word_count = (sizeof(T) + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t);

 public:
  Seqlock() noexcept { store(T{}); sequence_.store(0, std::memory_order_relaxed); }
  explicit Seqlock(const T& initial) noexcept { store(initial); sequence_.store(0, std::memory_order_relaxed); }

  /// Publishes `value`. One writer thread only. Wait-free, allocation-free.
  void store(const T& value) noexcept {
    const std::uint64_t sequence = sequence_.load(std::memory_order_relaxed);
    sequence_.store(sequence + 1, std::memory_order_relaxed);  // odd: write in progress
    std::array<std::uint64_t, word_count> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    // Release stores order the odd sequence before every payload word.
    for (std::size_t i = 0; i < word_count; ++i) words_[i].store(words[i], std::memory_order_release);
    sequence_.store(sequence + 2, std::memory_order_release);
  }

  /// Copies the latest complete value into `value` and returns true; returns false (and leaves
  /// `value` untouched) when a write was in progress. Wait-free.
  bool try_load(T& value) const noexcept {
    const std::uint64_t before = sequence_.load(std::memory_order_acquire);
    if (before & 1U) return false;
    std::array<std::uint64_t, word_count> words{};
    for (std::size_t i = 0; i < word_count; ++i) words[i] = words_[i].load(std::memory_order_acquire);
    if (sequence_.load(std::memory_order_relaxed) != before) return false;
    std::memcpy(static_cast<void*>(&value), words.data(), sizeof(T));
    return true;
  }

  /// The latest complete value, retrying while a write is in progress (not for the haptic tick:
  /// a writer preempted mid-write would make it wait).
  T load() const noexcept {
    T value{};
    while (!try_load(value)) {
    }
    return value;
  }

  /// Number of completed stores (even: no write in progress).
  std::uint64_t version() const noexcept { return sequence_.load(std::memory_order_acquire) / 2; }

 private:
  std::atomic<std::uint64_t> sequence_{0};
  std::array<std::atomic<std::uint64_t>, word_count> words_{};
};

}  // namespace touchstone::realtime::concurrency
