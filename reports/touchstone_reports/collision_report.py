"""The report of a `touchstone collision` run: Table 1 replica, tremor, per-cycle cost.

Reads OUTPUT_DIR/results.json and writes OUTPUT_DIR/report.md and, unless plots are off, the PNGs
table1_overlap_tests.png, tremor_error.png and cycle_cost.png into OUTPUT_DIR (report.md links
those present). Every number is read from results.json; the study settings the text quotes are in
its "settings" section.
"""
import json
import math
import os

from .common import load_json, pyplot, save_figure, write_report

# The paper's Table 1: overlap tests at first contact against the triangle count.
PAPER_TABLE1 = [(500, 9), (2500, 12), (17000, 14), (35000, 16)]

PLOTS = ("table1_overlap_tests.png", "tremor_error.png", "cycle_cost.png")


# ------------------------------------------------------------------------------------------ cells

def c_format(spec, value):
    """printf-style formatting of a number (the C formats "%.1f", "%.0f", ...)."""
    return spec % value


def dump(value):
    """A JSON scalar as JSON spells it (integers as digits, null as "null")."""
    return json.dumps(value)


def cell(value, spec):
    """`spec` of a number, "–" for null."""
    return "–" if value is None else c_format(spec, value)


def mean_max_cell(mm, mean_spec="%.1f"):
    """"mean / max" of a {mean, max} pair (max without decimals), "–" when there is no mean."""
    if mm.get("mean") is None:
        return "–"
    return cell(mm["mean"], mean_spec) + " / " + cell(mm["max"], "%.0f")


def millimetres_cell(metres):
    """A length [m] in mm with 3 decimals; null is a ray that missed: "miss"."""
    return "miss" if metres is None else "%.3f" % (1e3 * metres)


def percent_cell(fraction):
    """A fraction as a percentage with 1 decimal."""
    return "%.1f %%" % (100 * fraction)


# ------------------------------------------------------------------------------------------ plots

def plot_table1(plt, results, out):
    """Nodes entered at first contact against the triangle count (binary trees, stomach organs),
    with the single-path depth D − 1 and the paper's Table 1."""
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
    ax.plot([p[0] for p in PAPER_TABLE1], [p[1] for p in PAPER_TABLE1], "r*", markersize=11, label="paper, Table 1")
    ax.set_xscale("log")
    ax.set_xlabel("triangles")
    ax.set_ylabel("overlap tests (levels) at first contact")
    ax.set_title("Table 1 replica: binary tree, stomach-like organ")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(plt, fig, os.path.join(out, "table1_overlap_tests.png"))


def plot_tremor(plt, results, out):
    """Predicted-point error (median, p90, max) against the window, one panel per tremor amplitude."""
    rows = results["tremor"]
    amplitudes = sorted({r["amplitude_m"] for r in rows})
    if not amplitudes:
        return

    def mm(v):
        return math.nan if v is None else 1e3 * v

    fig, axes = plt.subplots(1, len(amplitudes), figsize=(4.2 * len(amplitudes), 3.8), sharey=True, squeeze=False)
    for ax, a in zip(axes[0], amplitudes):
        for period in sorted({r["sample_period_cycles"] for r in rows if r["amplitude_m"] == a}):
            rs = sorted((r for r in rows if r["amplitude_m"] == a and r["sample_period_cycles"] == period),
                        key=lambda r: r["window_s"])
            x = [1e3 * r["window_s"] for r in rs]
            rate = rs[0]["sample_rate_hz"]
            line, = ax.plot(x, [mm(r["error_m"]["median"]) for r in rs], "o-", label=f"median, {rate:.0f} Hz")
            ax.plot(x, [mm(r["error_m"]["p90"]) for r in rs], "^--", color=line.get_color(), label=f"p90, {rate:.0f} Hz")
            ax.plot(x, [mm(r["error_m"]["max"]) for r in rs], "v:", color=line.get_color(), label=f"max, {rate:.0f} Hz")
        ax.axhline(1.0, color="k", linewidth=0.8)
        ax.axhline(5.0, color="r", linewidth=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("window m × sampling period [ms]")
        ax.set_title(f"tremor {1e3 * a:.2f} mm RMS per axis")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("predicted-point error [mm] (misses not drawn)")
    axes[0][-1].legend(fontsize=7)
    save_figure(plt, fig, os.path.join(out, "tremor_error.png"))


def cost_pairs(results):
    """cycle_cost rows in pairs (full detection, prediction), one pair per case."""
    cost = results["cycle_cost"]
    return [(cost[i], cost[i + 1]) for i in range(0, len(cost) - 1, 2)]


def plot_cycle_cost(plt, results, out):
    """Box tests per cycle before contact: full detection against prediction, per case."""
    pairs = cost_pairs(results)
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
    save_figure(plt, fig, os.path.join(out, "cycle_cost.png"))


def make_plots(results, out):
    """The three PNGs into `out`."""
    plt = pyplot()
    plot_table1(plt, results, out)
    plot_tremor(plt, results, out)
    plot_cycle_cost(plt, results, out)


# ------------------------------------------------------------------------------------------ text

def header_section(md, d):
    """Title, provenance, organs."""
    prov = d["provenance"]
    md.append("# " + d["study"] + ": collision detection and prediction\n\n"
              "Written by `touchstone collision` (git " + str(prov.get("git", "?")) + ", " + str(prov.get("build_type", "?"))
              + ", " + str(prov.get("compiler", "?")) + "; machine: " + str(prov.get("machine", "?")) + "). Numbers are "
              "those of `results.json`; CSV: `table1.csv`, `tremor.csv`, `cycle_cost.csv`. Run time "
              + "%.1f" % d["time_s"]["total"] + " s.\n\n")
    md.append("## Organs\n\n| organ | triangles | vertices | mesh size [mm] | meshing [s] |\n|---|---:|---:|---:|---:|\n")
    for o in d["organs"]:
        md.append("| %s | %s | %s | %.2f | %.2f |\n" % (o["id"], dump(o["triangles"]), dump(o["vertices"]),
                                                        1e3 * o["mesh_size_m"], o["mesh_s"]))


def prediction_per_free_cycle(d, organ_id):
    """The prediction's measured cost per free cycle for an organ (any tree: it makes no surface
    query there) and the share of cheap approach cycles; "–" when not measured."""
    for c in d["cycle_cost"]:
        if c["organ"] == organ_id and c["mode"] == "prediction":
            e = c["prediction"]
            if e["free_cycle_distances_min"] == 1 and e["free_cycle_distances_max"] == 1:
                cost = "1 distance + 1 comparison"
            else:
                cost = dump(e["free_cycle_distances_min"]) + "–" + dump(e["free_cycle_distances_max"]) + " distances"
            return cost + " (" + percent_cell(e["cheap_fraction_before_contact"]) + " of approach cycles)"
    return "–"


def table1_section(md, d, plot):
    """Table 1 replica per organ (binary tree, OBB and AABB), then every tree with query times."""
    s = d["settings"]
    md.append("\n## Table 1 replica: overlap tests of the query that finds the first contact\n\n"
              + dump(s["trajectories"]) + " approach trajectories per organ (tremor "
              + "%.2f" % (1e3 * s["approach_tremor_rms_per_axis_m"])
              + " mm RMS per axis); full detection tests the tip's motion segment every cycle, and the count is that of "
              "the contact cycle's query, mean / max over the trajectories. *Nodes entered* = (box tests − 1) / 2, the "
              "levels a single root-to-leaf path descends in a binary tree without entry grid — the count the paper "
              "reports (one test per level); *binary levels* = the tree's depth D (a single path: D − 1 nodes entered, "
              "2D − 1 box tests). With prediction a free cycle costs 1 distance + 1 comparison and no overlap test; the "
              "last column gives the share of the cycles before contact that were free or deferred (the rest: corridor "
              "advances, re-predictions and full detection near the surface, see *per-cycle cost*).\n\n")
    md.append("| organ | triangles | binary levels D | single path D − 1 | paper | OBB nodes entered | OBB box tests | "
              "OBB triangle tests | AABB nodes entered | AABB box tests | AABB triangle tests | prediction per free cycle |\n"
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n")
    for o in d["organs"]:
        obb = aabb = None
        for r in d["table1"]:
            if r["organ"] == o["id"] and r["tree"] == "binary":
                if r["bounding_volume"] == "obb":
                    obb = r
                else:
                    aabb = r
        if obb is None and aabb is None:
            continue
        any_row = obb if obb is not None else aabb

        def part(r, key):
            return mean_max_cell(r[key]) if r is not None else "–"

        paper = any_row.get("paper_overlap_tests")
        md.append("| " + " | ".join([
            o["id"], dump(o["triangles"]), dump(any_row["binary_depth"]), str(any_row["binary_depth"] - 1),
            "–" if paper is None else dump(paper),
            part(obb, "nodes_entered"), part(obb, "box_tests"), part(obb, "triangle_tests"),
            part(aabb, "nodes_entered"), part(aabb, "box_tests"), part(aabb, "triangle_tests"),
            prediction_per_free_cycle(d, o["id"])]) + " |\n")
    md.append("\nHow to read it: the paper's numbers are about log2 n, one test per level of a balanced binary tree — "
              "the *single path* column. The contact cycle's segment crosses the surface, where the boxes of neighbouring "
              "triangles overlap, so it enters both children at some levels: *nodes entered* counts every inner node "
              "the traversal entered and is the measured cost; box tests count both children's boxes per entered node "
              "plus the root's.\n")
    plot.note()
    plot("table1_overlap_tests.png", "Table 1 replica: nodes entered against the triangle count")
    md.append("\nEvery tree, with the time of the first-contact query alone (the least of three means over repeated "
              "passes, after a warm-up pass; the comparison with Embree on the same queries is "
              "`benchmarks/collision_benchmark` (`first_contact/...` against `first_contact_embree/...`): Embree is not "
              "linked into this program).\n\n"
              "| organ | tree | volume | depth | contacts | box tests | triangle tests | overlap tests | query [ns] | build [ms] |\n"
              "|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n")
    for r in d["table1"]:
        md.append("| " + " | ".join([
            r["organ"], r["tree"], r["bounding_volume"], dump(r["depth"]), dump(r["first_contacts"]),
            mean_max_cell(r["box_tests"]), mean_max_cell(r["triangle_tests"]), mean_max_cell(r["overlap_tests"]),
            cell(r["query_time_ns"], "%.0f"), cell(r["build_ms"], "%.1f")]) + " |\n")


def tremor_section(md, d, plot):
    """The predicted-point error distribution per amplitude, window and sampling rate."""
    t = d["settings"]["tremor"]
    md.append("\n## Tremor: predicted-point error of the mean tool path (eq. 2)\n\n"
              "Organ " + d["tremor_organ"] + "; " + dump(t["trajectories"])
              + " approaches per amplitude from ≥ " + "%.0f" % (1e3 * t["start_distance_min_m"])
              + " mm; the prediction is made when the smooth hand is " + "%.1f" % (1e3 * t["evaluate_at_m"])
              + " mm from the point it will touch; error = distance from the ray's hit to that point (a ray that misses "
              "the organ counts as an infinite error: *miss*). m = 1 at 1 kHz is eq. 1 (no filtering). Paper: > 5 mm "
              "without filtering, < 1 mm with it.\n\n"
              "| tremor RMS/axis [mm] | m | sampling [Hz] | window [ms] | median [mm] | p90 [mm] | max [mm] | misses |\n"
              "|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    for r in d["tremor"]:
        md.append("| " + " | ".join([
            "%.2f" % (1e3 * r["amplitude_m"]), dump(r["window_samples"]), "%.0f" % r["sample_rate_hz"],
            "%.0f" % (1e3 * r["window_s"]), millimetres_cell(r["error_m"]["median"]),
            millimetres_cell(r["error_m"]["p90"]), millimetres_cell(r["error_m"]["max"]), dump(r["no_hit"])]) + " |\n")
    plot("tremor_error.png", "Predicted-point error against the window")


def cost_row(full, predicted, phase, with_tree):
    """One per-cycle cost row: full detection's and the prediction's means per cycle in a phase."""
    f = full["phases"][phase]
    p = predicted["phases"][phase]
    cells = [full["organ"]]
    if with_tree:
        cells += [full["tree"], full["bounding_volume"]]
    cells += [phase, dump(f["cycles"]), cell(f["surface_queries_per_cycle"], "%.3f"), cell(f["box_tests_per_cycle"], "%.2f"),
              cell(f["triangle_tests_per_cycle"], "%.2f"),
              cell(f["time_ns"]["median"], "%.0f") + " / " + cell(f["time_ns"]["trimmed_mean"], "%.0f") + " / "
              + cell(f["time_ns"]["p99"], "%.0f"),
              cell(p["distances_per_cycle"], "%.3f"), cell(p["surface_queries_per_cycle"], "%.3f"),
              cell(p["box_tests_per_cycle"], "%.2f"), cell(p["triangle_tests_per_cycle"], "%.2f"),
              cell(p["time_ns"]["median"], "%.0f") + " / " + cell(p["time_ns"]["trimmed_mean"], "%.0f") + " / "
              + cell(p["time_ns"]["p99"], "%.0f")]
    return "| " + " | ".join(cells) + " |\n"


def cycle_cost_section(md, d, plot):
    """Per-cycle cost: every tree (approach, whole run), every phase of the detailed tree, prediction events."""
    s = d["settings"]
    pr = s["prediction"]
    md.append("\n## Per-cycle cost over whole approach–contact–release runs\n\n"
              "Full detection: the tip's motion segment against the surface every cycle outside, an inside test in "
              "contact. Prediction: `CollisionPredictor` (m = " + dump(pr["window_samples"]) + " every "
              + dump(pr["sample_period_cycles"]) + " cycles, straight-line range "
              + "%.1f" % (1e3 * pr["straight_line_range_m"])
              + " mm); in contact it runs the same inside test. Phases from full detection: approach (before the first "
              "contact), contact, release (after it). Per cycle, means: distances (point–point: the predictor's ball "
              "checks), surface queries (segment, ray, closest point, inside), box and triangle tests; time per cycle "
              "in ns: median / mean* / p99, mean* = the mean of the fastest 99.9 % of the cycles (the machine is shared: "
              "the slowest are preemptions; means and maxima of all cycles are in `results.json`). Times include "
              "reading the clock, " + cell(d["timer_overhead_ns"], "%.0f") + " ns per cycle (an empty timed "
              "region, median).\n\n")
    columns = ("cycles | full: queries | full: box tests | full: triangle tests | full: ns median / mean* / p99 | "
               "pred.: distances | pred.: queries | pred.: box tests | pred.: triangle tests | pred.: ns median / mean* / p99 |\n")
    alignment = "---:|---:|---:|---:|---|---:|---:|---:|---:|---|\n"
    pairs = cost_pairs(d)
    md.append("Every tree: the approach and the whole run.\n\n| organ | tree | volume | phase | " + columns
              + "|---|---|---|---|" + alignment)
    for full, predicted in pairs:
        for phase in ("approach", "all"):
            md.append(cost_row(full, predicted, phase, True))
    tree, volume = s["detailed_tree"], s["detailed_bounding_volume"]
    md.append("\nEvery phase, tree `" + tree + "`, " + volume + " (every tree in `cycle_cost.csv`).\n\n"
              "| organ | phase | " + columns + "|---|---|" + alignment)
    for full, predicted in pairs:
        if full["tree"] == tree and full["bounding_volume"] == volume:
            for phase in ("approach", "contact", "release", "all"):
                md.append(cost_row(full, predicted, phase, False))
    plot("cycle_cost.png", "Box tests per cycle before contact, full detection and prediction")
    md.append("\nPrediction events (all trajectories of a case): misses and spurious contacts are counted against "
              "full detection on the same tip positions.\n\n"
              "| organ | tree | volume | free cycles | distances per free cycle (min–max) | cheap approach cycles | "
              "predictions | re-predictions | closest-point queries | ray casts | full detections | contacts | misses | "
              "spurious |\n"
              "|---|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    for r in d["cycle_cost"]:
        if r["mode"] != "prediction":
            continue
        e = r["prediction"]
        md.append("| " + " | ".join([
            r["organ"], r["tree"], r["bounding_volume"], dump(e["free_cycles"]),
            dump(e["free_cycle_distances_min"]) + "–" + dump(e["free_cycle_distances_max"]),
            percent_cell(e["cheap_fraction_before_contact"]), dump(e["predictions"]), dump(e["repredictions"]),
            dump(e["closest_point_queries"]), dump(e["ray_casts"]), dump(e["full_detections"]), dump(e["contacts"]),
            dump(e["misses"]), dump(e["spurious_contacts"])]) + " |\n")


class PlotLinks:
    """Links a PNG from the report when it exists in the output folder; `note()` says once why
    there are no plots."""

    def __init__(self, md, out, plot_note):
        self.md, self.out, self.plot_note = md, out, plot_note

    def note(self):
        if self.plot_note:
            self.md.append("\n(No plots: " + self.plot_note + ".)\n")

    def __call__(self, file, caption):
        if os.path.exists(os.path.join(self.out, file)):
            self.md.append("\n![" + caption + "](" + file + ")\n")


def render(results, out, plot_note=""):
    """The report's text; `plot_note` (non-empty: why there are no plots) is printed below Table 1."""
    md = []
    plot = PlotLinks(md, out, plot_note)
    header_section(md, results)
    table1_section(md, results, plot)
    tremor_section(md, results, plot)
    cycle_cost_section(md, results, plot)
    return "".join(md)


def write(out, plots=True, plot_note=None):
    """Reads out/results.json, writes the plots (unless `plots` is False) and report.md; returns
    the report's path. Without plots the report says why: `plot_note`, default "not asked for"."""
    results = load_json(out)
    if plots:
        make_plots(results, out)
        note = ""
    else:
        note = plot_note or "not asked for"
    return write_report(out, render(results, out, note))
