#!/usr/bin/env python3
"""Runs one Google Benchmark program on a small filter for a few milliseconds per case, and fails
when it runs no case, exits non-zero, or a case reports an error (SkipWithError does not change
the exit status, so the JSON output is read). Timings are not checked: speed is measured by the
benchmarks themselves, on a quiet machine, never by the test run.

Usage: run_benchmark_smoke.py <benchmark program> <filter regex>
"""
import json
import subprocess
import sys
import tempfile


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    program, pattern = sys.argv[1], sys.argv[2]
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        run = subprocess.run([program, f"--benchmark_filter={pattern}", "--benchmark_min_time=0.01",
                              f"--benchmark_out={out.name}", "--benchmark_out_format=json"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=600)
        if run.returncode != 0:
            print(f"{program} exited with {run.returncode}:\n{run.stderr}")
            return 1
        with open(out.name, encoding="utf-8") as f:
            text = f.read()
        # With no matching case the program writes no JSON at all.
        cases = json.loads(text).get("benchmarks", []) if text.strip() else []
    if not cases:
        print(f"{program}: no benchmark matches '{pattern}'")
        return 1
    failed = [c for c in cases if c.get("error_occurred")]
    for c in failed:
        print(f"{c['name']}: {c.get('error_message', 'error')}")
    print(f"{program}: {len(cases)} case(s) ran, {len(failed)} with an error")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
