#!/usr/bin/env bash
# Fuzzes every parser: configures and builds the `fuzz` preset (clang, libFuzzer, ASan + UBSan),
# then runs each harness for SECONDS (default 60) on a scratch copy of its committed corpus
# (tests/fuzz/corpus/<harness>), and prints per harness the executions, executions per second
# and findings. Exits non-zero on any finding (crash, sanitizer report, leak, timeout, out of
# memory); the inputs are kept in build/fuzz/findings/<harness>/.
#   scripts/fuzz.sh [SECONDS] [HARNESS...]     e.g. scripts/fuzz.sh 600 fuzz_msh_reader
set -euo pipefail
cd "$(dirname "$0")/.."

seconds="${1:-60}"
shift || true
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then
  echo "fuzz.sh: SECONDS must be a positive integer, got '$seconds'" >&2
  exit 2
fi

launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake --preset fuzz "${launcher[@]}" >/dev/null
./scripts/build.sh --preset fuzz -j "${TOUCHSTONE_FUZZ_BUILD_JOBS:-$(nproc)}"

build=build/fuzz
harnesses=("$@")
if ((${#harnesses[@]} == 0)); then
  for corpus in tests/fuzz/corpus/*/; do harnesses+=("$(basename "$corpus")"); done
fi

# Any sanitizer report ends the run with a crash input saved. Leaks are checked after every
# input (libFuzzer's -detect_leaks, on by default with ASan), but for the VTK ones listed in
# tests/lsan_suppressions.txt (why there). An allocation beyond what ASan supports (2^40
# bytes) fails as in a release build, where the readers turn it into an error naming the file;
# one beyond -rss_limit_mb is still a finding.
asan_options="detect_leaks=1:allocator_may_return_null=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan_suppressions.txt:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"

findings_total=0
summary=()
for harness in "${harnesses[@]}"; do
  binary="$build/tests/fuzz/$harness"
  [[ -x "$binary" ]] || { echo "fuzz.sh: no harness $binary" >&2; exit 2; }
  scratch="$build/scratch/$harness"
  findings="$build/findings/$harness"
  rm -rf "$scratch"
  mkdir -p "$scratch" "$findings"
  cp tests/fuzz/corpus/"$harness"/* "$scratch"/
  log="$build/logs/$harness.log"
  mkdir -p "$(dirname "$log")"
  before=$(find "$findings" -type f | wc -l)
  echo "== $harness: ${seconds} s"
  status=0
  # The VTK libraries have no frame pointers: only the slow unwinder reaches the frame that
  # names the library in a leak's stack, which the suppressions match (it costs speed).
  unwind=""
  [[ "$harness" == fuzz_surface_* ]] && unwind=":fast_unwind_on_malloc=0"
  ASAN_OPTIONS="$asan_options$unwind" "$binary" "$scratch" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$findings/" >"$log" 2>&1 || status=$?
  after=$(find "$findings" -type f | wc -l)
  executions=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  new_findings=$((after - before))
  if ((status != 0 && new_findings == 0)); then new_findings=1; fi  # a failure that saved no input
  findings_total=$((findings_total + new_findings))
  line=$(printf "%-26s executions %10s   exec/s %7s   findings %d" "$harness" "${executions:-?}" "${rate:-?}" \
    "$new_findings")
  summary+=("$line")
  echo "$line"
  if ((new_findings > 0)); then
    echo "   log: $log; inputs: $findings/"
    grep -m 5 -E "ERROR: |runtime error|SUMMARY|escaped|deadly signal" "$log" | sed 's/^/   /' || true
  fi
done

echo
echo "fuzz.sh: ${seconds} s per harness"
printf '%s\n' "${summary[@]}"
if ((findings_total > 0)); then
  echo "fuzz.sh: $findings_total finding(s)" >&2
  exit 1
fi
