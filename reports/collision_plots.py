#!/usr/bin/env python3
"""Plots of `touchstone collision`: reads <out>/results.json, writes PNGs there.

    /usr/bin/python3 reports/collision_plots.py output/collision_table1

- table1_overlap_tests.png: nodes entered / box tests at first contact against the triangle
  count (binary trees), with the paper's Table 1 numbers and the single-path depth;
- tremor_error.png: predicted-point error (median with p90 and max) against the window, one
  panel per tremor amplitude;
- cycle_cost.png: box tests per cycle before contact, full detection against prediction.
The touchstone program calls it after writing results.json; report.md links the PNGs it made.
"""
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def table1(results, out):
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    rows = [r for r in results["table1"] if r["tree"] == "binary" and r["organ"].startswith("stomach")]
    for volume, marker in (("obb", "o"), ("aabb", "s")):
        rs = sorted((r for r in rows if r["bounding_volume"] == volume), key=lambda r: r["triangles"])
        if not rs or rs[0]["nodes_entered"]["mean"] is None:
            continue
        n = [r["triangles"] for r in rs]
        ax.errorbar(n, [r["nodes_entered"]["mean"] for r in rs],
                    yerr=[[0] * len(rs), [r["nodes_entered"]["max"] - r["nodes_entered"]["mean"] for r in rs]],
                    marker=marker, capsize=3, label=f"{volume.upper()} nodes entered (mean, bar to max)")
    depth = sorted({(r["triangles"], r["binary_depth"] - 1) for r in rows})
    if depth:
        ax.plot([d[0] for d in depth], [d[1] for d in depth], "k--", label="single path (D − 1)")
    paper = [(500, 9), (2500, 12), (17000, 14), (35000, 16)]
    ax.plot([p[0] for p in paper], [p[1] for p in paper], "r*", markersize=11, label="paper, Table 1")
    ax.set_xscale("log")
    ax.set_xlabel("triangles")
    ax.set_ylabel("overlap tests (levels) at first contact")
    ax.set_title("Table 1 replica: binary tree, stomach-like organ")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "table1_overlap_tests.png"), dpi=120)
    plt.close(fig)


def tremor(results, out):
    rows = results["tremor"]
    amplitudes = sorted({r["amplitude_m"] for r in rows})
    if not amplitudes:
        return
    fig, axes = plt.subplots(1, len(amplitudes), figsize=(4.2 * len(amplitudes), 3.8), sharey=True, squeeze=False)
    for ax, a in zip(axes[0], amplitudes):
        for period, marker in sorted({(r["sample_period_cycles"], None) for r in rows if r["amplitude_m"] == a}):
            rs = sorted((r for r in rows if r["amplitude_m"] == a and r["sample_period_cycles"] == period),
                        key=lambda r: r["window_s"])
            x = [1e3 * r["window_s"] for r in rs]

            def mm(v):
                return math.nan if v is None else 1e3 * v

            median = [mm(r["error_m"]["median"]) for r in rs]
            p90 = [mm(r["error_m"]["p90"]) for r in rs]
            worst = [mm(r["error_m"]["max"]) for r in rs]
            rate = rs[0]["sample_rate_hz"]
            line, = ax.plot(x, median, "o-", label=f"median, {rate:.0f} Hz")
            ax.plot(x, p90, "^--", color=line.get_color(), label=f"p90, {rate:.0f} Hz")
            ax.plot(x, worst, "v:", color=line.get_color(), label=f"max, {rate:.0f} Hz")
        ax.axhline(1.0, color="k", linewidth=0.8)
        ax.axhline(5.0, color="r", linewidth=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("window m × sampling period [ms]")
        ax.set_title(f"tremor {1e3 * a:.2f} mm RMS per axis")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("predicted-point error [mm] (misses not drawn)")
    axes[0][-1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "tremor_error.png"), dpi=120)
    plt.close(fig)


def cycle_cost(results, out):
    cost = results["cycle_cost"]
    pairs = [(cost[i], cost[i + 1]) for i in range(0, len(cost) - 1, 2)]
    if not pairs:
        return
    labels = [f'{f["organ"]}\n{f["tree"]} {f["bounding_volume"]}' for f, _ in pairs]
    full = [f["phases"]["approach"]["box_tests_per_cycle"] or 0 for f, _ in pairs]
    pred = [p["phases"]["approach"]["box_tests_per_cycle"] or 0 for _, p in pairs]
    fig, ax = plt.subplots(figsize=(max(6.4, 0.45 * len(pairs)), 4.2))
    x = range(len(pairs))
    ax.bar([i - 0.2 for i in x], full, width=0.4, label="full detection every cycle")
    ax.bar([i + 0.2 for i in x], pred, width=0.4, label="prediction")
    ax.set_xticks(list(x))
    ax.set_xticklabels(labels, rotation=90, fontsize=7)
    ax.set_ylabel("box tests per cycle before contact (mean)")
    ax.set_title("Per-cycle cost during the approach")
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "cycle_cost.png"), dpi=120)
    plt.close(fig)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: collision_plots.py <output folder of touchstone collision>")
    out = sys.argv[1]
    with open(os.path.join(out, "results.json")) as f:
        results = json.load(f)
    table1(results, out)
    tremor(results, out)
    cycle_cost(results, out)


if __name__ == "__main__":
    main()
