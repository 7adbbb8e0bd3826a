#include "touchstone/realtime/runtime/loop_timing.hpp"

#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
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
