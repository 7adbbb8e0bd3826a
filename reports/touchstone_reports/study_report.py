"""The report of a `touchstone study` run: MFS against the converged FEM reference.

Reads OUTPUT_DIR/results.json and writes OUTPUT_DIR/report.md with PNG plots in OUTPUT_DIR/plots/
(force_depth, force_error_vs_n, pareto, displacement_axis, and per problem force_error_vs_n_<name>
and point_tool_force_vs_n_<name>). Every number in the report is read from results.json.
"""
import math
import os

from .common import Markdown, finite, get, load_json, mn, pct, pyplot, seconds, write_report


class Study:
    """results.json and the selections every section uses."""

    def __init__(self, results, output_dir):
        self.results = results
        self.output_dir = output_dir
        self.plots = os.path.join(output_dir, "plots")
        self.problem = results["problem"]
        self.ref = results.get("reference_summary") or {}  # null when --only skipped the first problem
        self.ref_unc = self.ref.get("uncertainty_rel")
        self.series = results.get("series", [])
        # Several problems ([problems.<name>] variants): the plots and the detailed tables are the
        # first problem's; every problem has its own section (its errors, notes, flags).
        self.problems = results.get("problems") or [{"name": None}]
        self.first = self.problems[0]["name"]
        self.several = len(self.problems) > 1
        all_cases = results["cases"]
        self.cases = [c for c in all_cases if of_problem(c, self.first)]
        self.mfs_all = [c for c in all_cases if c["model"] == "mfs"]
        self.mfs = [c for c in self.cases if c["model"] == "mfs"]
        self.by_series = {s["name"]: sorted([c for c in self.mfs if c.get("series") == s["name"]],
                                            key=lambda c: c["params"]["node_count_requested"]) for s in self.series}
        self.fem_levels = [c for c in self.cases if c["model"] == "fem" and isinstance(get(c, "params", "refinement"), int)]
        self.ref_case = next((c for c in self.cases if c["id"] == self.ref.get("case")), None)
        self.depths_mm = [1e3 * d for d in results["depths_m"]]


def of_problem(case, name):
    """A case belongs to problem `name` (None: the study has a single problem)."""
    return name is None or get(case, "params", "problem") in (name, None)


def finish(plt, fig, ax, xlabel, ylabel, title, path, log_grid=False):
    """Labels, grid and legend of a report plot; writes it to `path` and closes it."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both" if log_grid else "major")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def flags_text(case):
    """The case's accuracy flags as inline code, comma-separated ("" when none)."""
    flags = get(case, "accuracy", "flags") or []
    return ", ".join("`%s`" % f for f in flags) if flags else ""


def problem_values_text(v):
    """The problem's values in one line: benchmark, θ, E, ν, contact, angle to the normal, δ_max, L."""
    if not v:
        return ""
    text = "%s" % v.get("benchmark")
    if v.get("benchmark") == "B5":
        text += " θ = %.0f°" % math.degrees(v.get("contact_polar_angle_rad") or 0.0)
    text += ", E = %g Pa, ν = %g, %s" % (v.get("youngs_modulus_Pa"), v.get("poisson_ratio"), v.get("contact"))
    if finite(v.get("angle_to_normal_rad")) and v["angle_to_normal_rad"] > 1e-9:
        text += ", d %.0f° off the normal" % math.degrees(v["angle_to_normal_rad"])
    text += ", δ_max = %g mm, L = %g mm" % (1e3 * v["depths_m"][-1], 1e3 * v.get("local_radius_m"))
    return text


# ------------------------------------------------------------------------------------------ plots

def plot_force_depth(plt, s):
    """Force against depth: the reference, the half-space closed form, the smallest and largest N of every series."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    if s.ref_case:
        ax.plot(s.depths_mm, [1e3 * f for f in s.ref_case["force_depth_N"]], "k-", lw=2.5,
                label="FEM reference (Richardson)")
    # The half-space closed form the reference study adds on B1 and B2: Sneddon (frictionless) or
    # Mossakovskii (bonded), named from its formula.
    for c in (c for c in s.cases if c["model"] == "analytic" and c.get("part") == "reference"):
        formula = str(get(c, "params", "formula") or "")
        name = "Mossakovskii" if formula.startswith("Mossakovskii") else "Sneddon"
        ax.plot(s.depths_mm, [1e3 * f for f in c["force_depth_N"]], "k:", label="half-space (%s)" % name)
    for series in s.series:
        group = [c for c in s.by_series[series["name"]] if c["status"] == "ok"]
        for c in ([group[0], group[-1]] if len(group) > 1 else group):
            ax.plot(s.depths_mm, [1e3 * f if finite(f) else float("nan") for f in c["force_depth_N"]], "o--", ms=3,
                    label="MFS %s N=%d" % (series["name"], c["params"]["node_count"]))
    finish(plt, fig, ax, "tool-tip depth δ [mm]", "tool force along d [mN]",
           "Force against depth (%s, %s)" % (s.problem["benchmark"], s.problem["contact"]),
           os.path.join(s.plots, "force_depth.png"))


def plot_force_error_vs_n(plt, s):
    """Force error against N per series, with the 1 % / 5 % targets and the reference's own error."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for series in s.series:
        pts = [(c["params"]["node_count"], c["error"]["force_rel"]) for c in s.by_series[series["name"]]
               if finite(get(c, "error", "force_rel")) and c["status"] == "ok"]
        if pts:
            ax.loglog([p[0] for p in pts], [100 * p[1] for p in pts], "o-",
                      label="MFS %s (%s%s)" % (series["name"], series["formulation"],
                                               ", engine default" if series.get("engine_default") else ""))
    for target, n_max, style in ((1.0, 300, "g--"), (5.0, 60, "g:")):
        ax.plot([20, n_max], [target, target], style, lw=1)
        ax.annotate("target %g %% (N ≤ %d)" % (target, n_max), (20, target), fontsize=7, va="bottom")
    if finite(s.ref_unc) and s.ref_unc > 0:
        ax.axhline(100 * s.ref_unc, color="grey", lw=1)
        ax.annotate("reference's own error estimate %s" % pct(s.ref_unc), (20, 100 * s.ref_unc), fontsize=7, va="bottom")
    finish(plt, fig, ax, "MFS nodes N", "force error vs FEM reference [%]", "Force error against node count",
           os.path.join(s.plots, "force_error_vs_n.png"), log_grid=True)


def pareto_front(points):
    """The (time, error, id) points not beaten by a faster one: sorted by time, error falling."""
    front, best = [], float("inf")
    for p in sorted(points):
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def plot_pareto(plt, s):
    """Error against run time over every configuration, MFS and FEM levels, with the Pareto front."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    points = []
    for series in s.series:
        pts = [(c["time_s"]["total"], c["error"]["force_rel"], c["id"]) for c in s.by_series[series["name"]]
               if finite(get(c, "error", "force_rel")) and finite(get(c, "time_s", "total")) and c["status"] == "ok"]
        if pts:
            ax.loglog([p[0] for p in pts], [100 * p[1] for p in pts], "o", label="MFS %s" % series["name"])
            points += pts
    fem_ok = [c for c in s.fem_levels if finite(get(c, "error", "force_rel")) and c["error"]["force_rel"] > 0
              and finite(get(c, "time_s", "total"))]
    fem_pts = [(c["time_s"]["total"], c["error"]["force_rel"], c["id"]) for c in fem_ok]
    for part, marker in (("reference", "s"), ("table2_fem", "D"), ("table2_reference", "^")):
        pts = [p for p, c in zip(fem_pts, fem_ok) if c.get("part") == part]
        if pts:
            ax.loglog([p[0] for p in pts], [100 * p[1] for p in pts], marker, mfc="none", label="FEM %s levels" % part)
    points += fem_pts
    front = pareto_front(points)
    if front:
        ax.loglog([p[0] for p in front], [100 * p[1] for p in front], "k-", lw=1, label="Pareto front")
    ax.axhline(5.0, color="g", ls=":", lw=1)
    finish(plt, fig, ax, "run time (build + solve) [s]", "force error [%]", "Error against run time",
           os.path.join(s.plots, "pareto.png"), log_grid=True)


def axis_profile(problem, probes):
    """The "axis*" probes as (depth below the contact point along d [a], displacement along d [mm]), sorted by depth."""
    a = problem["tool_radius_m"]
    d = problem["direction"]
    norm = math.sqrt(sum(x * x for x in d))
    cp = problem["contact_point_m"]
    xs, ys = [], []
    for p in probes or []:
        if not p["name"].startswith("axis") or not p.get("found") or p.get("displacement_m") is None:
            continue
        depth = sum((p["position_m"][i] - cp[i]) * d[i] for i in range(3)) / norm
        u = sum(p["displacement_m"][i] * d[i] for i in range(3)) / norm
        xs.append(depth / a)
        ys.append(1e3 * u)
    order = sorted(range(len(xs)), key=lambda i: xs[i])
    return [xs[i] for i in order], [ys[i] for i in order]


def plot_displacement_axis(plt, s):
    """Displacement profile along the axis below the tool: the reference and the largest N of every series."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    if s.ref_case:
        x, y = axis_profile(s.problem, get(s.ref_case, "qoi", "probes"))
        ax.plot(x, y, "k-s", lw=2, label="FEM reference (finest mesh)")
    for series in s.series:
        group = [c for c in s.by_series[series["name"]] if c["status"] == "ok"]
        if group:
            x, y = axis_profile(s.problem, get(group[-1], "qoi", "probes"))
            ax.plot(x, y, "o--", label="MFS %s N=%d" % (series["name"], group[-1]["params"]["node_count"]))
    finish(plt, fig, ax, "depth below the contact point along d [a]",
           "displacement along d [mm] at δ = %.3g mm" % (1e3 * s.results["depths_m"][-1]), "Displacement along the axis",
           os.path.join(s.plots, "displacement_axis.png"))


# ------------------------------------------------------------------------------------------ text

def header_section(w, s):
    """Title, provenance, the problem, its notes, the reference and its mesh families."""
    results, problem, ref = s.results, s.problem, s.ref
    prov = results["provenance"]
    w("# Study `%s`: MFS against the converged FEM reference" % results["study"])
    w("")
    w("Generated by the `touchstone_reports` package (reports/) from `results.json` (every number below is read from "
      "it: relative errors are 100 x the stored value, rounded to 2 decimals). Git %s, %s build, %s, %s, config "
      "sha256 %s…, %s." % (prov.get("git"), prov.get("build_type"), prov.get("compiler"), prov.get("machine"),
                           str(prov.get("config_sha256"))[:12], prov.get("time_utc")))
    w("")
    b1 = problem["benchmark"] == "B1"
    if b1:
        where = "at the centre of the flat top face z = 0 (base z = −W clamped)"
    elif problem["benchmark"] == "B5":
        where = "at polar angle θ = %.1f°" % math.degrees(problem.get("contact_polar_angle_rad") or 0.0)
    else:
        where = "at the pole"
    if s.several:
        w("This study has **%d problems** (variants of its [problem]); the plots and the detailed tables are those of "
          "the first, `%s`; every problem's errors, notes and flags follow in \"Problems\"." % (len(s.problems), s.first))
        w("")
    w("**Problem**%s (both models): %s, %s = %g mm, tool radius a = %g mm, L = %g mm, E = %g kPa, ν = %g, %s rigid flat "
      "punch %s, direction %s, depth ramp δ = %s mm. Both models are linear: each case is solved once at "
      "the largest δ; the force at every δ of the ramp is K_t δ d (MFS, the engine's haptic force) or F_ref δ/δ_max "
      "(FEM). Probe points (the axis below the tool and the %s, inside 0.9 L) are identical for both." %
      (" `%s`" % s.first if s.several else "", problem["benchmark"] + (" (cylinder, radius = height = W)" if b1 else ""),
       "W" if b1 else "R", 1e3 * problem["body_radius_m"], 1e3 * problem["tool_radius_m"],
       1e3 * problem["local_radius_m"], problem["youngs_modulus_Pa"] / 1e3, problem["poisson_ratio"],
       problem["contact"], where, problem["direction"], ", ".join("%g" % x for x in s.depths_mm),
       "radial line on the top face" if b1 else "surface meridian"))
    w("")
    for note in s.problems[0].get("notes", []) if not s.several else []:
        w("**Note** (%s): %s." % (note["id"], note["text"]))
        w("")
    w("**Reference**: `%s` = %s mN at δ = %g mm; estimated discretisation error **%s** (the larger of the "
      "mesh-family spread %s and each family's Richardson uncertainty); %s. Displacement reference: `%s`, "
      "estimated error %s (relative change of the probes from the second-finest to the finest mesh)." %
      (ref.get("case"), mn(ref.get("axial_force_N")), s.depths_mm[-1], pct(s.ref_unc, 3),
       pct(ref.get("family_spread_rel"), 3),
       "asymptotic convergence" if ref.get("asymptotic") else "**not in the asymptotic range: treat with care**",
       ref.get("probes_from"), pct(ref.get("disp_uncertainty_rel"))))
    w("")
    if finite(ref.get("half_space_force_N")):
        w("**Half-space closed form** (%s): %s mN at δ = %g mm; the reference is %.4f x it (a finite body with a "
          "clamped base is stiffer than the half-space; the MFS columns \"vs half-space\" below are signed errors "
          "against this closed form)." % (ref.get("half_space_formula"), mn(ref["half_space_force_N"]), s.depths_mm[-1],
                                          ref.get("ratio_to_half_space") or float("nan")))
        w("")
    for fam in ref.get("families", []):
        levels = ", ".join("%d dofs: %s mN" % (level["dofs"], mn(level["axial_force_N"])) for level in fam["levels"])
        w("- %s: %s → extrapolated %s mN (observed order %s, uncertainty %s)" %
          (fam["problem"], levels, mn(fam.get("extrapolated_force_N")),
           ("%.2f" % fam["observed_order"]) if finite(fam.get("observed_order")) else "n/a",
           pct(fam.get("extrapolated_relative_uncertainty"), 3)))
    w("")


def target_cells(t):
    """(required, measured) of a target row, in the target's unit: relative, s, or a speed-up factor."""
    if t["unit"] == "relative":
        return "≤ " + pct(t["target"]), pct(t.get("measured"))
    if t["unit"] == "s":
        return "≤ " + seconds(t["target"]), seconds(t.get("measured"))
    return "≥ %g x" % t["target"], ("%.3g x" % t["measured"]) if finite(t.get("measured")) else "n/a"


def targets_section(w, s):
    """Every target: required, measured, met or missed, and the case it is measured on."""
    targets = s.results["targets"]
    w("## Targets")
    w("")
    missed = [t for t in targets if t.get("met") is False]
    met = [t for t in targets if t.get("met") is True]
    w("%d met, **%d missed**, %d not measured by this study." % (len(met), len(missed), len(targets) - len(met) - len(missed)))
    w("")
    w("| target | required | measured | verdict | case |")
    w("|---|---|---|---|---|")
    for t in targets:
        req, val = target_cells(t)
        verdict = "met" if t.get("met") is True else ("**MISSED**: " + t.get("shortfall", "") if t.get("met") is False
                                                       else t.get("shortfall", "not measured"))
        w("| %s | %s | %s | %s | `%s` |" % (t["what"], req, val, verdict, t.get("basis", "")))
    w("")
    w("Speed rows are single wall-clock samples of this run on a shared machine; the benchmarks "
      "(`touchstone bench`) carry the speed claims.")
    w("")


def table2_section(w, s):
    """The paper's Table 2 beside ours: nodes, model / solution / total time, force error."""
    t2 = s.results.get("table2", {})
    paper = t2.get("paper", {})
    ours = t2.get("ours", {})
    w("## Table 2 replica (paper: Kim, De & Srinivasan 2002)")
    w("")
    cols = [("paper FE", paper.get("fe")), ("paper MFS", paper.get("mfs"))]
    if ours.get("fe"):
        cols.append(("ours FE (%s)" % ours["fe"]["case"].split("/")[0], ours["fe"]))
    if ours.get("mfs"):
        cols.append(("ours MFS %s" % ours["mfs"]["series"], ours["mfs"]))
    if ours.get("mfs_default") and ours.get("mfs_default") != ours.get("mfs"):
        cols.append(("ours MFS %s (engine default)" % ours["mfs_default"]["series"], ours["mfs_default"]))
    whole = ours.get("mfs_default_whole_body")
    if whole:
        cols.append(("ours MFS %s (engine default, whole hemisphere)" % whole["series"], whole))
    default_note = t2.get("mfs_default_note")
    w("| | " + " | ".join(c[0] for c in cols) + " |")
    w("|---|" + "---|" * len(cols))
    w("| No. of nodes | " + " | ".join(str(c[1].get("nodes")) if c[1] else "n/a" for c in cols) + " |")
    w("| Model time | " + " | ".join(seconds(c[1].get("model_s")) if c[1] else "n/a" for c in cols) + " |")
    w("| Solution time | " + " | ".join(seconds(c[1].get("solution_s")) if c[1] else "n/a" for c in cols) + " |")
    w("| Total time | " + " | ".join(seconds(c[1].get("total_s")) if c[1] else "n/a" for c in cols) + " |")
    w("| Force error | not reported | not reported | " + " | ".join(
        "%s (reference ±%s)" % (pct(c[1].get("force_rel")), pct(c[1].get("reference_uncertainty_rel"), 3)) if c[1] else "n/a"
        for c in cols[2:]) + " |")
    if default_note:
        w("")
        w("No engine-default row: %s." % default_note)
    if any(c[1] and "force_rel_full_domain" in c[1] for c in cols[2:]):
        w("| Force error vs full hemisphere B2 | | | " + " | ".join(
            pct(c[1].get("force_rel_full_domain")) if c[1] and "force_rel_full_domain" in c[1] else "" for c in cols[2:]) + " |")
    w("")
    if ours.get("fe"):
        fe = ours["fe"]
        fe_case = next((c for c in s.cases if c["id"] == fe["case"]), {})
        processes = get(fe_case, "solver", "mpi_processes")
        w("Ours FE: %s nodes are P2 support points (%s mesh vertices, %s dofs), full hemisphere B2; model = read + "
          "setup + assembly, solution = %s, on %s MPI process%s; meshing took a further %s (end to end %s). "
          "Its force error is against `%s` = %s mN." % (
              fe["nodes"], fe["mesh_vertices"], fe["dofs"], get(fe_case, "solver", "name") or "the linear solve",
              processes, "" if processes == 1 else "es",
              seconds(fe["mesh_s"]), seconds(fe["end_to_end_s"]), fe["reference"], mn(fe["reference_force_N"])))
    if s.problem["benchmark"] == "B3":
        against = "the FEM on the identical local domain (B3)"
    else:
        against = ("the FEM on the whole body (%s): the MFS solves organ ∩ ball(contact, L) with u = 0 on the cut, so "
                   "these errors include its truncation" % s.problem["benchmark"])
    w("Ours MFS: model = sprinkling + shape functions + assembly; solution = factorisation + condensation to the "
      "tool stiffness K_t + the solve for δ (one build serves every δ). MFS errors are against %s. Paper times: %s." %
      (against, paper.get("machine")))
    if whole:
        w("")
        w("The whole-hemisphere column is the paper's own comparison: the same engine default with its exterior "
          "from the organ atlas (`%s`), its force error against the converged FEM of the whole hemisphere B2." %
          whole["case"])
    w("")


def force_error_section(w, s):
    """Force error per series and N (the first problem), the accuracy flags' meaning, forces by extraction method."""
    results = s.results
    w("## Force error against node count")
    w("")
    w("![force error against N](plots/force_error_vs_n.png)")
    w("")
    w("Reference's own estimated discretisation error: **%s** (shown next to every error)." % pct(s.ref_unc, 3))
    w("")
    w("Accuracy flags (reference-free, from what the engine reports; thresholds in `accuracy_thresholds` of "
      "results.json): `force_methods_disagree` = the independent force estimators differ by more than %s, "
      "`supports_grew` = adaptive support growth was needed, `ill_conditioned` = a moment matrix within %gx of the "
      "engine's rcond failure threshold, `stiffness_implausible` = the tool stiffness outside %g–%gx the half-space "
      "punch's, `unconverged_in_n` = the force moved by more than %s from the series' previous N (the series has not "
      "converged to that accuracy; the change under-estimates the error)." % (
          pct(get(results, "accuracy_thresholds", "force_method_spread_limit"), 0),
          get(results, "accuracy_thresholds", "rcond_margin") or float("nan"),
          get(results, "accuracy_thresholds", "stiffness_ratio_min") or float("nan"),
          get(results, "accuracy_thresholds", "stiffness_ratio_max") or float("nan"),
          pct(get(results, "accuracy_thresholds", "force_change_limit"), 0)))
    w("")
    half_space = any(get(c, "error_half_space") for c in s.mfs)
    w("| case | formulation | N (actual) | F [mN] | force error | signed | ref. error | displacement error (rel. L2) | max abs. difference [µm] | vs full B2 | %stime | status | accuracy flags |"
      % ("vs half-space (signed) | " if half_space else ""))
    w("|---|---|---|---|---|---|---|---|---|---|---|---|---|" + ("---|" if half_space else ""))
    for series in s.series:
        for c in s.by_series[series["name"]]:
            e = c["error"]
            hs = (pct(get(c, "error_half_space", "force_signed_rel")) + " | ") if half_space else ""
            w("| `%s` | %s%s | %s | %s | %s | %s | ±%s | %s | %s | %s | %s%s | %s | %s |" % (
                c["id"], c["params"].get("formulation"), " (paper mode)" if c["params"].get("paper_mode") else "",
                c["params"].get("node_count"), mn(get(c, "qoi", "axial_force_N")), pct(e.get("force_rel")),
                pct(e.get("force_signed_rel")), pct(e.get("reference_uncertainty_rel"), 3), pct(e.get("disp_rel_l2")),
                ("%.2f" % (1e6 * e["disp_max_m"])) if finite(e.get("disp_max_m")) else "n/a",
                pct(get(c, "error_full_domain", "force_rel")), hs, seconds(get(c, "time_s", "total")), c["status"],
                flags_text(c)))
    w("")
    w("Engine default formulation: `%s`. Forces by extraction method (signed error against the reference):"
      % results.get("default_formulation"))
    w("")
    w("| case | traction integral | reaction | paper partition | energy |")
    w("|---|---|---|---|---|")
    for c in s.mfs:
        m = c["error"].get("by_method_signed_rel", {})
        w("| `%s` | %s | %s | %s | %s |" % (c["id"], pct(m.get("traction_integral")), pct(m.get("reaction")),
                                            pct(m.get("paper_partition")), pct(m.get("energy_along_tool"))))
    w("")


def point_tool_section(w, plt, p, group, plots):
    """B4: the paper's point tool at each N beside the FEM punch of radius s(N), its tip spacing."""
    punches = {round(1e6 * q["punch_radius_m"]): q["summary"] for q in p.get("punch_references") or []}
    rows = sorted((c for c in group if finite(get(c, "params", "tip_spacing_m"))),
                  key=lambda c: (c.get("series"), c["params"]["node_count"]))
    if not rows:
        return
    w("B4: each MFS case (the paper's point tool) against the FEM of a flat punch of radius s, the case's tip-node "
      "spacing. Both forces depend on the resolution; the FEM column is converged for its s (its own error next to it).")
    w("")
    w("| case | N | tip spacing s [mm] | MFS F [mN] | FEM punch a = s: F [mN] | its error | MFS − FEM |")
    w("|---|---|---|---|---|---|---|")
    for c in rows:
        ref = punches.get(round(1e6 * c["params"]["fem_punch_radius_m"]), {})
        w("| `%s` | %s | %.3f | %s | %s | %s | %s |" % (
            c["id"], c["params"]["node_count"], 1e3 * c["params"]["tip_spacing_m"], mn(get(c, "qoi", "axial_force_N")),
            mn(ref.get("axial_force_N")), pct(ref.get("uncertainty_rel"), 3), pct(get(c, "error", "force_signed_rel"))))
    w("")
    ok = [c for c in rows if c["status"] == "ok" and finite(get(c, "qoi", "axial_force_N"))]
    if not ok:
        return
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot([c["params"]["node_count"] for c in ok], [1e3 * c["qoi"]["axial_force_N"] for c in ok], "o-",
            label="MFS, paper's point tool")
    fem = [(c["params"]["node_count"], punches.get(round(1e6 * c["params"]["fem_punch_radius_m"]), {}).get("axial_force_N"))
           for c in ok]
    fem = [q for q in fem if finite(q[1])]
    ax.plot([q[0] for q in fem], [1e3 * q[1] for q in fem], "s--", label="FEM, punch radius = tip spacing s(N)")
    ax.set_xscale("log")
    plot = "point_tool_force_vs_n_%s.png" % p["name"]
    finish(plt, fig, ax, "MFS nodes N", "tool force at max depth [mN]", "B4: both models depend on the resolution",
           os.path.join(plots, plot))
    w("![B4 forces](plots/%s)" % plot)
    w("")


def problems_section(w, plt, s):
    """One row per problem variant, its notes, and one error-against-N plot and table each."""
    w("## Problems")
    w("")
    w("| problem | values | replaced keys | reference | reference F [mN] | its error | MFS cases | ok | flagged | failed |")
    w("|---|---|---|---|---|---|---|---|---|---|")
    for p in s.problems:
        group = [c for c in s.mfs_all if get(c, "params", "problem") == p["name"]]
        ok = [c for c in group if c["status"] == "ok"]
        flagged = [c for c in ok if get(c, "accuracy", "flags")]
        rs = p.get("reference_summary") or {}
        w("| `%s` | %s | %s | `%s` | %s | %s | %d | %d | %d | %d |" % (
            p["name"], problem_values_text(p.get("problem")), ", ".join(p.get("overridden_keys", [])) or "-",
            rs.get("case", "not run"), mn(rs.get("axial_force_N")), pct(rs.get("uncertainty_rel"), 3), len(group),
            len(ok), len(flagged), len(group) - len(ok)))
    w("")
    for p in s.problems:
        for note in p.get("notes", []):
            w("- **`%s`** (%s): %s." % (p["name"], note["id"], note["text"]))
    w("")
    for p in s.problems:
        name = p["name"]
        group = [c for c in s.mfs_all if get(c, "params", "problem") == name]
        if not group:
            continue
        w("### Problem `%s`" % name)
        w("")
        if (p.get("problem") or {}).get("point_tool"):
            point_tool_section(w, plt, p, group, s.plots)
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        names = []
        for c in group:
            if c.get("series") not in names:
                names.append(c.get("series"))
        for sname in names:
            pts = sorted((c["params"]["node_count"], c["error"]["force_rel"]) for c in group
                         if c.get("series") == sname and c["status"] == "ok" and finite(get(c, "error", "force_rel"))
                         and c["error"]["force_rel"] > 0)
            if pts:
                ax.loglog([q[0] for q in pts], [100 * q[1] for q in pts], "o-", label="MFS %s" % sname)
        if ax.lines:
            plot = "force_error_vs_n_%s.png" % name
            finish(plt, fig, ax, "MFS nodes N", "force error vs FEM reference [%]", "Force error, problem %s" % name,
                   os.path.join(s.plots, plot), log_grid=True)
            w("![force error, %s](plots/%s)" % (name, plot))
            w("")
        else:
            plt.close(fig)
        w("| case | N | F [mN] | force error | displacement error | force-method spread | status | flags |")
        w("|---|---|---|---|---|---|---|---|")
        for c in group:
            w("| `%s` | %s | %s | %s | %s | %s | %s | %s |" % (
                c["id"], c["params"].get("node_count"), mn(get(c, "qoi", "axial_force_N")),
                pct(get(c, "error", "force_rel")), pct(get(c, "error", "disp_rel_l2")),
                pct(get(c, "accuracy", "force_method_spread")), c["status"], flags_text(c)))
        w("")


def failures_section(w, s):
    """Every MFS case that failed or ended "ok" with an accuracy flag, with its parameters."""
    failed = [c for c in s.mfs_all if c["status"] != "ok"]
    flagged = [c for c in s.mfs_all if c["status"] == "ok" and get(c, "accuracy", "flags")]
    w("## Failures and accuracy flags")
    w("")
    w("%d MFS case%s failed with a status, %d ended \"ok\" with an accuracy flag, %d ended \"ok\" unflagged." % (
        len(failed), "" if len(failed) == 1 else "s", len(flagged), len(s.mfs_all) - len(failed) - len(flagged)))
    w("")
    if not failed and not flagged:
        return
    w("| case | problem | series knobs | status | flags | force-method spread | rcond min | support scale | force error |")
    w("|---|---|---|---|---|---|---|---|---|")
    for c in failed + flagged:
        pa = c["params"]
        knobs = "%s, N = %s, radius factors %g / %g, max support scale %g, seed %s" % (
            pa.get("formulation") + (" (paper mode)" if pa.get("paper_mode") else ""), pa.get("node_count_requested"),
            pa.get("radius_factor"), pa.get("boundary_radius_factor"), pa.get("max_support_scale"), pa.get("seed"))
        acc = c.get("accuracy", {})
        w("| `%s` | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            c["id"], problem_values_text(pa.get("problem_values")), knobs, c["status"], flags_text(c),
            pct(acc.get("force_method_spread")),
            ("%.2e" % acc["rcond_min"]) if finite(acc.get("rcond_min")) else "n/a",
            ("%.3g" % acc["support_scale_max"]) if finite(acc.get("support_scale_max")) else "n/a",
            pct(get(c, "error", "force_rel"))))
    w("")
    w("rcond and support scale: over the collocation points (collocation) or the volume quadrature points (Galerkin); "
      "\"n/a\" when a case failed before reporting them.")
    w("")


def closing_sections(w, s):
    """Error against run time (FEM levels), force against depth, displacement along the axis, the data files."""
    w("## Error against run time")
    w("")
    w("![Pareto front](plots/pareto.png)")
    w("")
    w("| FEM level | dofs | F [mN] | force error | total time |")
    w("|---|---|---|---|---|")
    for c in s.fem_levels:
        w("| `%s` | %s | %s | %s | %s |" % (c["id"], get(c, "mesh", "dofs"), mn(get(c, "qoi", "axial_force_N")),
                                          pct(get(c, "error", "force_rel")), seconds(get(c, "time_s", "total"))))
    w("")
    w("## Force against depth")
    w("")
    w("![force against depth](plots/force_depth.png)")
    w("")
    w("## Displacement along the axis")
    w("")
    w("![displacement along the axis](plots/displacement_axis.png)")
    w("")
    w("Data: `results.json`, `cases.csv`, `force_depth.csv`, `probes.csv`, `targets.csv`; FEM VTU in `fem/*/vtu/`, "
      "MFS node clouds in `mfs/<case>/`.")


def render(results, output_dir):
    """The plots (written into output_dir/plots) and the report's text."""
    plt = pyplot()
    s = Study(results, output_dir)
    os.makedirs(s.plots, exist_ok=True)
    plot_force_depth(plt, s)
    plot_force_error_vs_n(plt, s)
    plot_pareto(plt, s)
    plot_displacement_axis(plt, s)
    w = Markdown()
    header_section(w, s)
    targets_section(w, s)
    table2_section(w, s)
    force_error_section(w, s)
    if s.several:
        problems_section(w, plt, s)
    elif (results.get("problem") or {}).get("point_tool"):
        w("## B4: the point tool against the punch of its tip spacing")
        w("")
        point_tool_section(w, plt, s.problems[0], s.mfs_all, s.plots)
    failures_section(w, s)
    closing_sections(w, s)
    return w.text()


def write(output_dir):
    """Reads output_dir/results.json, writes the plots and report.md; returns the report's path."""
    results = load_json(output_dir)
    pyplot()  # fail on a missing matplotlib before any work
    return write_report(output_dir, render(results, output_dir))
