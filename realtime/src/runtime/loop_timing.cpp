#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <unistd.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <thread>

namespace touchstone::realtime::runtime {

void LatenessHistogram::add(double lateness_s) noexcept {
  if (!std::isfinite(lateness_s)) return;
  lateness_s = std::max(0.0, lateness_s);
  ++count_;
  sum_s_ += lateness_s;
  max_s_ = std::max(max_s_, lateness_s);
  const double bin = lateness_s / bin_width_s;
  if (bin >= bin_count) ++overflow_;
  else ++bins_[static_cast<std::size_t>(bin)];
}

double LatenessHistogram::quantile(double q) const noexcept {
  if (count_ == 0) return 0;
  q = std::clamp(q, 0.0, 1.0);
  const auto rank = static_cast<long long>(std::ceil(q * static_cast<double>(count_)));
  long long seen = 0;
  for (int i = 0; i < bin_count; ++i) {
    seen += bins_[i];
    if (seen >= std::max(rank, 1LL)) return (i + 1) * bin_width_s;  // upper edge: never optimistic
  }
  return max_s_;
}

long long LatenessHistogram::count_above(double threshold_s) const noexcept {
  // Bins whose lower edge is at or above the threshold (a tolerance absorbs the division's rounding).
  const auto first = static_cast<long long>(std::ceil(threshold_s / bin_width_s - 1e-9));
  long long above = overflow_;
  for (long long i = std::max(0LL, first); i < bin_count; ++i) above += bins_[static_cast<std::size_t>(i)];
  return above;
}

bool keep_freed_memory_for_reuse() noexcept {
#ifdef __GLIBC__
  return mallopt(M_MMAP_THRESHOLD, static_cast<int>(heap_block_limit_bytes)) == 1 &&
         mallopt(M_TRIM_THRESHOLD, static_cast<int>(heap_trim_bytes)) == 1;
#else
  return false;
#endif
}

std::string transparent_huge_page_mode() {
  std::ifstream file("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  if (!file || !std::getline(file, line)) return "unavailable";
  // The selected mode is the bracketed word: "always [madvise] never".
  const std::size_t open = line.find('['), close = line.find(']');
  if (open == std::string::npos || close == std::string::npos || close < open) return "unavailable";
  return line.substr(open + 1, close - open - 1);
}

std::string heap_huge_pages_description() {
  const std::size_t bytes = heap_bytes_on_huge_pages();
  const std::string mode = transparent_huge_page_mode();
  if (bytes == 0) return "no (kernel mode: " + mode + ")";
  return std::to_string(bytes >> 20) + " MiB advised (kernel mode: " + mode + ")";
}

namespace {
std::atomic<std::size_t> heap_bytes_advised{0};
}  // namespace

std::size_t heap_bytes_on_huge_pages() noexcept { return heap_bytes_advised.load(); }

std::size_t advise_huge_pages_for_heap() noexcept {
#ifdef __GLIBC__
  // A block larger than the free space at the heap's top (so the heap must grow, by the block
  // plus the pad); it must stay below keep_freed_memory_for_reuse()'s memory-map limit.
  const std::size_t probe_bytes = mallinfo2().keepcost + (std::size_t{1} << 20);
  if (probe_bytes >= heap_block_limit_bytes) return 0;
  constexpr std::size_t default_top_pad_bytes = std::size_t{128} << 10;  // glibc's M_TOP_PAD default
  const long page_bytes = sysconf(_SC_PAGESIZE);
  if (page_bytes <= 0) return 0;
  auto* const before = static_cast<char*>(sbrk(0));
  if (before == reinterpret_cast<char*>(-1)) return 0;
  if (mallopt(M_TOP_PAD, static_cast<int>(heap_huge_page_reserve_bytes)) != 1) return 0;
  void* const probe = std::malloc(probe_bytes);
  if (probe != nullptr) static_cast<volatile char*>(probe)[0] = 0;  // used, so that it is not elided
  std::free(probe);
  auto* const after = static_cast<char*>(sbrk(0));
  // The heap did not grow by the reserve (a data-size limit, a memory-mapped probe): the pad
  // goes back to the default, or every later growth would try for the reserve again. (Freeing
  // the probe trims the top to the pad less the allocator's bookkeeping: a little under it.)
  if (after == reinterpret_cast<char*>(-1) || after <= before ||
      static_cast<std::size_t>(after - before) < heap_huge_page_reserve_bytes / 2) {
    mallopt(M_TOP_PAD, static_cast<int>(default_top_pad_bytes));
    return 0;
  }
  // The free space at the heap's top, where the next blocks come from, begins below the old end
  // when the heap had free space there before: advise from its first page.
  const auto page_mask = ~(static_cast<std::uintptr_t>(page_bytes) - 1);
  auto* const start = reinterpret_cast<char*>(reinterpret_cast<std::uintptr_t>(after - mallinfo2().keepcost) & page_mask);
  const auto advised = static_cast<std::size_t>(after - start);
  if (madvise(start, advised, MADV_HUGEPAGE) != 0) return 0;  // a kernel without transparent huge pages
  heap_bytes_advised.store(advised);
  return advised;
#else
  return 0;
#endif
}

RealtimeThreadReport configure_realtime_thread(bool request_fifo, int priority) noexcept {
  RealtimeThreadReport report;
  report.timer_slack_set = prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL) == 0;
  if (!request_fifo) {
    report.note = "SCHED_FIFO not requested";
    return report;
  }
  sched_param parameters{};
  parameters.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &parameters);
  report.fifo = error == 0;
  if (!report.fifo)
    report.note = std::string("SCHED_FIFO refused (") + std::strerror(error) +
                  "): running at normal priority; grant CAP_SYS_NICE or an rtprio limit for real-time scheduling";
  else
    report.note = "SCHED_FIFO priority " + std::to_string(priority);
  return report;
}

DeadlineScheduler::DeadlineScheduler(double period_s, double spin_tail_s, Clock::time_point start) noexcept
    : period_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period_s))),
      spin_tail_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(spin_tail_s))),
      start_(start),
      deadline_(start) {}

double DeadlineScheduler::now_s() const noexcept {
  return std::chrono::duration<double>(Clock::now() - start_).count();
}

double DeadlineScheduler::wait() noexcept {
  deadline_ += period_;
  auto now = Clock::now();
  if (now > deadline_ + period_) {
    // Overran by more than a period: skip the missed deadlines instead of bursting through them.
    const auto missed = (now - deadline_) / period_;
    skipped_ += missed;
    deadline_ += missed * period_;
  }
  const auto wake = deadline_ - spin_tail_;
  if (now < wake) {
    // steady_clock is CLOCK_MONOTONIC on Linux: an absolute sleep on it has no drift.
    const auto since_epoch = std::chrono::duration_cast<std::chrono::nanoseconds>(wake.time_since_epoch()).count();
    timespec target{};
    target.tv_sec = static_cast<time_t>(since_epoch / 1000000000LL);
    target.tv_nsec = static_cast<long>(since_epoch % 1000000000LL);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &target, nullptr) == EINTR) {
    }
  }
  while ((now = Clock::now()) < deadline_) {
  }
  return std::chrono::duration<double>(now - deadline_).count();
}

}  // namespace touchstone::realtime::runtime
