#pragma once
/// @file
/// Timing of the runtime's periodic loops: an absolute-deadline scheduler
/// (sleep until shortly before the deadline, then spin — the kernel's wake-up is late by tens of
/// microseconds on a non-real-time kernel, the spin tail absorbs it) and a fixed-size histogram
/// of lateness, filled with no allocation, from which the run summary reports p50/p99/max and
/// missed deadlines.

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

namespace touchstone::realtime::runtime {

/// Lateness (actual start − deadline) of each tick, in 1 µs bins up to 20 ms; later ticks go
/// to an overflow count (their maximum is still exact).
class LatenessHistogram {
 public:
  static constexpr int bin_count = 20000;
  static constexpr double bin_width_s = 1e-6;

  void add(double lateness_s) noexcept;
  long long count() const noexcept { return count_; }
  /// The q-quantile (q in [0, 1]) to bin resolution [s]; 0 when empty.
  double quantile(double q) const noexcept;
  double max_s() const noexcept { return max_s_; }
  double mean_s() const noexcept { return count_ ? sum_s_ / static_cast<double>(count_) : 0.0; }
  /// Ticks later than `threshold_s`.
  long long count_above(double threshold_s) const noexcept;

 private:
  std::array<std::uint32_t, bin_count> bins_{};
  long long overflow_ = 0;
  long long count_ = 0;
  double max_s_ = 0;
  double sum_s_ = 0;
};

/// Summary of one loop for the run summary.
struct LoopStatistics {
  std::string name;
  double period_s = 0;
  long long ticks = 0;
  /// Lateness of the tick's start against its deadline [s].
  double lateness_p50_s = 0, lateness_p99_s = 0, lateness_max_s = 0;
  /// Ticks that started more than `late_threshold_s` after their deadline (0.5 ms for the
  /// haptic loop, whose target allows at most 0.2 % of ticks that late), and deadlines skipped
  /// entirely because a tick overran.
  long long late_ticks = 0;
  double late_threshold_s = 0;
  long long skipped_deadlines = 0;
  /// Work per tick (start to end) [s].
  double work_p50_s = 0, work_p99_s = 0, work_max_s = 0;
};

/// What the operating system granted a real-time thread.
struct RealtimeThreadReport {
  bool fifo = false;            ///< SCHED_FIFO granted
  bool timer_slack_set = false; ///< PR_SET_TIMERSLACK to 1 ns accepted
  std::string note;             ///< why not, in words, for the summary
};

/// Asks for SCHED_FIFO at `priority` (when `request_fifo`) and the smallest timer slack for the
/// calling thread. Never throws; a refusal is reported, not fatal.
RealtimeThreadReport configure_realtime_thread(bool request_fifo, int priority) noexcept;

/// Heap blocks up to this size come from the heap, not from fresh memory maps, and freed
/// memory is kept for reuse up to the trim size (keep_freed_memory_for_reuse()).
constexpr std::size_t heap_block_limit_bytes = std::size_t{64} << 20;
constexpr std::size_t heap_trim_bytes = std::size_t{256} << 20;

/// Makes the C library keep freed heap memory for reuse (glibc: blocks below
/// heap_block_limit_bytes are not memory-mapped, and the heap is not trimmed until
/// heap_trim_bytes are free at its top). A local model build allocates and frees its matrices
/// every time; with the library's adaptive defaults those blocks were mapped and returned again
/// and again, and each build paid the page faults of memory it had just freed (README, "Freed
/// memory is kept for reuse"). Process-wide: call once at start-up, before any thread starts.
/// False where the C library offers no such control.
bool keep_freed_memory_for_reuse() noexcept;

/// The heap reserve that advise_huge_pages_for_heap() grows the heap by and backs with
/// transparent huge pages (virtual address space: a page costs memory only once touched).
constexpr std::size_t heap_huge_page_reserve_bytes = std::size_t{1} << 30;

/// Grows the heap once by heap_huge_page_reserve_bytes and advises that range for transparent
/// huge pages (madvise MADV_HUGEPAGE), and keeps it: the heap then grows, and is trimmed, in
/// steps of the reserve. Where each first touch of a 4 KiB page is a trap to the kernel (on a
/// virtual machine, to the hypervisor too), a run that touches its memory once — mesh
/// generation, a sparse factorisation — spends much of its time in page faults; a 2 MiB page
/// takes one fault for 512 of them (README, "The heap on transparent huge pages"). Call after
/// keep_freed_memory_for_reuse() (the probe that grows the heap must come from the heap, not a
/// memory map) and before any thread starts. Returns the bytes advised; 0 where the C library,
/// the kernel (built without transparent huge pages) or the address space (a data-size limit)
/// does not allow it, in which case the heap is left as the C library manages it by default.
/// Under the kernel mode "never" the advice is accepted and changes nothing
/// (transparent_huge_page_mode() tells).
std::size_t advise_huge_pages_for_heap() noexcept;

/// What advise_huge_pages_for_heap() advised in this process (bytes; 0 before it or where it could not).
std::size_t heap_bytes_on_huge_pages() noexcept;

/// "always", "madvise" or "never": the kernel's transparent huge page mode, from
/// /sys/kernel/mm/transparent_hugepage/enabled; "unavailable" where that file is missing.
std::string transparent_huge_page_mode();

/// For a run's provenance: "1024 MiB advised (kernel mode: madvise)", or "no (kernel mode: never)".
std::string heap_huge_pages_description();

/// Periodic deadlines on the monotonic clock. wait() sleeps until `spin_tail` before the next
/// deadline, then spins to it; if the caller overran one or more deadlines it does not burst to
/// catch up: it skips them (counted) and aims for the next one in the future.
class DeadlineScheduler {
 public:
  using Clock = std::chrono::steady_clock;
  DeadlineScheduler(double period_s, double spin_tail_s, Clock::time_point start) noexcept;
  /// Waits for the next deadline; returns the lateness of the wake-up [s] (≥ 0).
  double wait() noexcept;
  /// Seconds since the start [s].
  double now_s() const noexcept;
  Clock::time_point deadline() const noexcept { return deadline_; }
  long long skipped() const noexcept { return skipped_; }

 private:
  Clock::duration period_, spin_tail_;
  Clock::time_point start_, deadline_;
  long long skipped_ = 0;
};

}  // namespace touchstone::realtime::runtime
