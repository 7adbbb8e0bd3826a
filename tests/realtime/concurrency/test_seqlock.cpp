// The Seqlock (realtime/concurrency/seqlock): a reader never sees a torn value, under a writer that
// never stops — the test ThreadSanitizer runs (tsan preset) to show the hand-off is race-free.
#include "touchstone/realtime/concurrency/seqlock.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <thread>

namespace touchstone::realtime::concurrency {
namespace {

/// Every word equals the sequence number: a torn read shows as words that differ.
struct Payload {
  std::array<std::uint64_t, 13> words{};
  double value = 0;
};

TEST(Seqlock, StoresAndLoadsAValue) {
  Seqlock<Payload> lock;
  EXPECT_EQ(lock.version(), 0U);
  Payload p;
  p.words.fill(7);
  p.value = 2.5;
  lock.store(p);
  EXPECT_EQ(lock.version(), 1U);
  Payload q;
  ASSERT_TRUE(lock.try_load(q));
  EXPECT_EQ(q.words, p.words);
  EXPECT_EQ(q.value, 2.5);
}

TEST(Seqlock, ReadersNeverSeeATornValue) {
  // The writer stores without pause until the reader has checked enough values, so the two
  // overlap however the threads are scheduled.
  Seqlock<Payload> lock;
  std::atomic<bool> stop{false};
  std::thread writer([&] {
    Payload p;
    for (std::uint64_t k = 1; !stop.load(std::memory_order_relaxed); ++k) {
      p.words.fill(k);
      p.value = static_cast<double>(k);
      lock.store(p);
    }
  });
  long long reads = 0, refused = 0;
  std::uint64_t first = 0, last = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while ((reads < 100000 || last == first) && std::chrono::steady_clock::now() < deadline) {
    Payload p;
    if (!lock.try_load(p)) {
      ++refused;
      continue;
    }
    ++reads;
    bool torn = false;
    for (const auto word : p.words) torn = torn || word != p.words[0];
    if (torn || p.value != static_cast<double>(p.words[0]) || p.words[0] < last) {
      stop = true;
      writer.join();
      FAIL() << "torn or backward read at value " << p.words[0] << " after " << reads << " reads";
    }
    if (first == 0) first = p.words[0];
    last = p.words[0];
  }
  stop = true;
  writer.join();
  EXPECT_GE(reads, 100000) << "the reader got too few values in 20 s";
  EXPECT_GT(last, first) << "the reader saw the writer make progress";
  EXPECT_GE(lock.version(), last);
}

}  // namespace
}  // namespace touchstone::realtime::concurrency
