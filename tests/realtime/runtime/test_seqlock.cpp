// The Seqlock (realtime/runtime/seqlock): a reader never sees a torn value, under a writer that
// never stops — the test ThreadSanitizer runs (tsan preset) to show the hand-off is race-free.
#include "touchstone/realtime/runtime/seqlock.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <thread>

namespace touchstone::realtime::runtime {
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
  Seqlock<Payload> lock;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    Payload p;
    for (std::uint64_t k = 1; k <= 200000; ++k) {
      p.words.fill(k);
      p.value = static_cast<double>(k);
      lock.store(p);
    }
    done = true;
  });
  long long reads = 0, refused = 0;
  std::uint64_t last = 0;
  while (!done.load()) {
    Payload p;
    if (!lock.try_load(p)) {
      ++refused;
      continue;
    }
    ++reads;
    for (const auto word : p.words) ASSERT_EQ(word, p.words[0]) << "torn read";
    ASSERT_EQ(p.value, static_cast<double>(p.words[0]));
    ASSERT_GE(p.words[0], last) << "values go back in time";
    last = p.words[0];
  }
  writer.join();
  EXPECT_GT(reads, 0);
  EXPECT_EQ(lock.load().words[0], 200000U);
  EXPECT_EQ(lock.version(), 200000U);
}

}  // namespace
}  // namespace touchstone::realtime::runtime
