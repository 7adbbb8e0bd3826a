// Loop timing (realtime/runtime/loop_timing): the lateness histogram's quantiles and counts,
// and the deadline scheduler's skipping of overrun deadlines. No wall-clock assertion beyond
// "not early": speed belongs to benchmarks.
#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <gtest/gtest.h>
#include <malloc.h>

#include <cstdlib>
#include <thread>

namespace touchstone::realtime::runtime {
namespace {

// After the call a block below the limit comes from the heap, not from a fresh memory map, and
// a block above it is still mapped. 48 MB is above the largest threshold glibc's own adaptation
// reaches (32 MB), so without the call it would be mapped: the test can fail.
TEST(KeepFreedMemoryForReuse, BuildSizedBlocksComeFromTheHeap) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers' allocators ignore the C library's settings";
#endif
  ASSERT_TRUE(keep_freed_memory_for_reuse());
  const auto mapped_blocks = [] { return mallinfo2().hblks; };
  const std::size_t before = mapped_blocks();
  void* block = std::malloc(std::size_t{48} << 20);
  ASSERT_NE(block, nullptr);
  static_cast<volatile char*>(block)[0] = 1;  // used, so that the allocation is not elided
  EXPECT_EQ(mapped_blocks(), before);
  std::free(block);
  void* large = std::malloc(heap_block_limit_bytes + (std::size_t{1} << 20));
  ASSERT_NE(large, nullptr);
  static_cast<volatile char*>(large)[0] = 1;
  EXPECT_EQ(mapped_blocks(), before + 1);
  std::free(large);
}

TEST(LatenessHistogram, QuantilesAreUpperBinEdges) {
  auto histogram = std::make_unique<LatenessHistogram>();
  EXPECT_EQ(histogram->quantile(0.5), 0.0);
  for (int i = 0; i < 100; ++i) histogram->add(i * 1e-6 + 0.5e-6);  // 0.5, 1.5, …, 99.5 µs
  EXPECT_EQ(histogram->count(), 100);
  EXPECT_NEAR(histogram->quantile(0.5), 50e-6, 1e-12);
  EXPECT_NEAR(histogram->quantile(0.99), 99e-6, 1e-12);
  EXPECT_NEAR(histogram->quantile(1.0), 100e-6, 1e-12);
  EXPECT_NEAR(histogram->max_s(), 99.5e-6, 1e-15);
  EXPECT_EQ(histogram->count_above(50e-6), 50);
  histogram->add(0.5);  // beyond the last bin: overflow, still counted and still the max
  EXPECT_EQ(histogram->count_above(50e-6), 51);
  EXPECT_EQ(histogram->max_s(), 0.5);
  histogram->add(-1.0);  // early counts as on time
  histogram->add(std::numeric_limits<double>::quiet_NaN());  // ignored
  EXPECT_EQ(histogram->count(), 102);
}

TEST(DeadlineScheduler, NeverWakesEarlyAndSkipsOverrunDeadlines) {
  const auto start = DeadlineScheduler::Clock::now();
  DeadlineScheduler scheduler(1e-3, 1e-4, start);
  for (int k = 1; k <= 20; ++k) {
    const double lateness = scheduler.wait();
    EXPECT_GE(lateness, 0.0);
    EXPECT_GE(DeadlineScheduler::Clock::now(), start + std::chrono::microseconds(1000 * k));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(10));  // overrun ~10 deadlines
  scheduler.wait();
  EXPECT_GE(scheduler.skipped(), 8);
  EXPECT_GE(DeadlineScheduler::Clock::now(), scheduler.deadline());
}

TEST(RealtimeThread, ReportsWhatWasGranted) {
  std::thread worker([] {
    const RealtimeThreadReport report = configure_realtime_thread(false, 80);
    EXPECT_FALSE(report.fifo);
    EXPECT_NE(report.note.find("not requested"), std::string::npos);
    const RealtimeThreadReport fifo = configure_realtime_thread(true, 80);
    // Granted or not depends on the machine; either way the note says which.
    EXPECT_NE(fifo.note.find("SCHED_FIFO"), std::string::npos);
  });
  worker.join();
}

}  // namespace
}  // namespace touchstone::realtime::runtime
