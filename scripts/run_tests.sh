#!/usr/bin/env bash
# The default test run on a fresh Debian 12 machine: install, build, run every test not
# labelled "large" (ctest -L large runs those), then the threaded tests under ThreadSanitizer,
# then every parser's fuzz harness for a few seconds. (scripts/run_sanitizers.sh runs the
# engine's tests under ASan + UBSan: not here, for its time; see its header.)
set -euo pipefail
cd "$(dirname "$0")/.."
# Each phase's wall time, so that a slower run says where the time went.
phase_start=$SECONDS
phase_done() {
  echo "run_tests: $1 took $((SECONDS - phase_start)) s"
  phase_start=$SECONDS
}
./scripts/install_deps.sh
phase_done "installing packages"
# The three builds need a few GB; a full disk otherwise shows only as a failed link.
echo "run_tests: free disk space: $(df -h --output=avail . | tail -1 | tr -d ' ')"
# CI sets TOUCHSTONE_WARNINGS_AS_ERRORS=ON: a new compiler warning fails the run.
cmake --preset release -DTOUCHSTONE_WARNINGS_AS_ERRORS="${TOUCHSTONE_WARNINGS_AS_ERRORS:-OFF}" >/dev/null
./scripts/build.sh --preset release -j "$(nproc)"
phase_done "the release build"
ctest --preset release -j "$(nproc)" "$@"
phase_done "the default tests"
# The threaded tests again under ThreadSanitizer (the threaded runtime must run clean): only
# their targets.
cmake --preset tsan >/dev/null
./scripts/build.sh --preset tsan --target threaded_tests -j "$(nproc)"
ctest --preset tsan-threaded -j "$(nproc)"
phase_done "the ThreadSanitizer build and tests"
# Every parser's libFuzzer harness briefly, from its committed corpus (scripts/fuzz.sh runs
# longer sessions): a crash, sanitizer report, leak or hang fails the run.
./scripts/fuzz.sh "${TOUCHSTONE_FUZZ_SMOKE_SECONDS:-10}"
phase_done "the fuzz build and smoke runs"
