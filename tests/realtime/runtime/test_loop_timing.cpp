// Loop timing (realtime/runtime/loop_timing): the lateness histogram's quantiles and counts,
// and the deadline scheduler's skipping of overrun deadlines. No wall-clock assertion beyond
// "not early": speed belongs to benchmarks.
#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <gtest/gtest.h>
#include <malloc.h>

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
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

// The kernel's flags of the mapping that holds `address` (the VmFlags line of /proc/self/smaps):
// "hg" marks a range advised for transparent huge pages.
std::string mapping_flags(const void* address) {
  std::ifstream smaps("/proc/self/smaps");
  const auto at = reinterpret_cast<std::uintptr_t>(address);
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    unsigned long first = 0, last = 0;
    char dash = 0;
    std::istringstream range(line);
    if (range >> std::hex >> first >> dash >> last && dash == '-') {
      inside = first <= at && at < last;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return "";
}

// After the call the heap holds a huge-page-advised reserve: a block allocated afterwards lies in
// a mapping the kernel marks "hg" (without the call, nothing in this test process advises the
// heap, so the flag would be absent: the test can fail). Run in one process after the test
// above, it finds a 48 MB block free at the heap's top: the call must grow the heap past that.
TEST(AdviseHugePagesForHeap, BlocksAllocatedAfterwardsLieInAnAdvisedRange) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers' allocators do not take blocks from the C library's heap";
#endif
  const std::string mode = transparent_huge_page_mode();
  if (mode == "unavailable") GTEST_SKIP() << "this kernel has no transparent huge pages";
  ASSERT_TRUE(mode == "always" || mode == "madvise" || mode == "never") << mode;
  ASSERT_TRUE(keep_freed_memory_for_reuse());
  const std::size_t advised = advise_huge_pages_for_heap();
  ASSERT_GE(advised, heap_huge_page_reserve_bytes / 2);
  EXPECT_EQ(heap_bytes_on_huge_pages(), advised);
  EXPECT_EQ(heap_huge_pages_description(), std::to_string(advised >> 20) + " MiB advised (kernel mode: " + mode + ")");
  void* block = std::malloc(std::size_t{8} << 20);
  ASSERT_NE(block, nullptr);
  static_cast<volatile char*>(block)[0] = 1;
  const std::string flags = mapping_flags(block);
  EXPECT_NE(flags.find(" hg"), std::string::npos) << "the block's mapping: " << flags;
  std::free(block);
}

TEST(TransparentHugePageMode, IsTheBracketedWordOfTheKernelsSetting) {
  std::ifstream file("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  if (!file || !std::getline(file, line)) {
    EXPECT_EQ(transparent_huge_page_mode(), "unavailable");
    return;
  }
  const std::string mode = transparent_huge_page_mode();
  EXPECT_NE(line.find("[" + mode + "]"), std::string::npos) << line;
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
