#!/usr/bin/env python3
"""Compares two builds of one Google Benchmark program on a machine whose speed drifts.

A shared VM can change speed by a factor of two within minutes, so two medians taken one after
the other compare the machine's moods, not the code. This runs the two binaries in alternation
(old, new, then new, old, ...), each pair close in time, and reports per benchmark the median
of the per-pair new/old time ratios with their range, next to each binary's median time.

    scripts/compare_benchmarks.py OLD NEW [--filter REGEX] [--pairs 8] [--min-time 0.15]

OLD and NEW are the two benchmark executables (e.g. the old revision's built in a git worktree).
The ratios are the figures to quote; the absolute times belong to the machine of that run.
"""
import argparse
import json
import statistics
import subprocess
import sys


def run(binary: str, name_filter: str, min_time: float) -> dict:
    try:
        completed = subprocess.run(
            [binary, f"--benchmark_filter={name_filter}", "--benchmark_format=json", f"--benchmark_min_time={min_time}"],
            capture_output=True, text=True, check=False)
    except OSError as error:
        sys.exit(f"compare_benchmarks: cannot run {binary}: {error.strerror}")
    if completed.returncode != 0:
        sys.exit(f"compare_benchmarks: {binary} exited with {completed.returncode}: {completed.stderr.strip()}")
    if not completed.stdout.strip():
        sys.exit(f"compare_benchmarks: {binary} ran no benchmark matching --filter '{name_filter}'")
    try:
        runs = json.loads(completed.stdout)["benchmarks"]
    except (json.JSONDecodeError, KeyError) as error:
        sys.exit(f"compare_benchmarks: {binary} printed no benchmark JSON ({error})")
    return {r["run_name"]: (r["real_time"], r["time_unit"]) for r in runs if r.get("run_type", "iteration") == "iteration"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("old")
    parser.add_argument("new")
    parser.add_argument("--filter", default=".", help="--benchmark_filter for both binaries")
    parser.add_argument("--pairs", type=int, default=8, help="alternating pairs of runs (default 8)")
    parser.add_argument("--min-time", type=float, default=0.15, help="--benchmark_min_time per run, s")
    args = parser.parse_args()
    if args.pairs < 1:
        sys.exit("compare_benchmarks: --pairs must be at least 1")

    ratios, old_times, new_times, units = {}, {}, {}, {}
    for pair in range(args.pairs):
        order = (args.old, args.new) if pair % 2 == 0 else (args.new, args.old)
        results = {binary: run(binary, args.filter, args.min_time) for binary in order}
        for name, (old_time, unit) in results[args.old].items():
            if name not in results[args.new]:
                continue
            new_time, new_unit = results[args.new][name]
            if new_unit != unit:
                sys.exit(f"compare_benchmarks: {name} is timed in {unit} by one binary and {new_unit} by the other")
            ratios.setdefault(name, []).append(new_time / old_time)
            old_times.setdefault(name, []).append(old_time)
            new_times.setdefault(name, []).append(new_time)
            units[name] = unit
    if not ratios:
        sys.exit("compare_benchmarks: no benchmark ran in both binaries (check --filter)")
    width = max(len(name) for name in ratios)
    print(f"{'benchmark':{width}s}  {'old median':>12s}  {'new median':>12s}  new/old: median (range), pairs")
    for name, values in ratios.items():
        unit = units[name]
        print(f"{name:{width}s}  {statistics.median(old_times[name]):9.3f} {unit:2s}  "
              f"{statistics.median(new_times[name]):9.3f} {unit:2s}  "
              f"{statistics.median(values):.3f} ({min(values):.3f}-{max(values):.3f}), {len(values)}")


if __name__ == "__main__":
    main()
