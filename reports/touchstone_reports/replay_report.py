"""The report of a palpation replay (`touchstone study` on a [replay] file): the forces of the
real-time model against the converged FEM reference, tick by tick, over a recorded palpation.

Reads OUTPUT_DIR/results.json, writes OUTPUT_DIR/report.md and OUTPUT_DIR/force_over_time.png
(matplotlib).
"""
import os

from .common import Markdown, fmt, get, load_json, pct, pyplot, save_figure, table, write_report


def plot(results, path):
    """Force magnitude of both models over time (top), the relative error of the force vector, and
    the angle between the two forces (direction error)."""
    plt = pyplot()
    columns = results.get("series_columns") or []
    rows = results.get("series") or []
    col = {name: i for i, name in enumerate(columns)}
    t = [r[col["time_s"]] for r in rows]
    fig, (top, bottom, angle) = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    top.plot(t, [1e3 * r[col["reference_force_N"]] for r in rows], ".", ms=1.5, label="reference FEM (Richardson)")
    top.plot(t, [1e3 * r[col["mfs_force_N"]] for r in rows], ".", ms=1.5, label="real-time MFS")
    top.set_ylabel("|F| [mN]")
    top.legend(loc="lower center", ncol=2, markerscale=6)
    rel = [(r[col["time_s"]], 100 * r[col["relative_error"]]) for r in rows if r[col["relative_error"]] is not None]
    bottom.plot([x for x, _ in rel], [y for _, y in rel], ".", ms=1.5, color="C3")
    bottom.axhline(5, color="0.5", lw=0.8, ls="--")
    bottom.set_ylabel("|F_mfs - F_ref| / |F_ref| [%]")
    bottom.set_ylim(bottom=0)
    if "angle_deg" in col:
        angle.plot(t, [r[col["angle_deg"]] for r in rows], ".", ms=1.5, color="C2")
    angle.set_ylabel("angle(F_mfs, F_ref) [deg]")
    angle.set_xlabel("run time [s]")
    angle.set_ylim(bottom=0)
    save_figure(plt, fig, path)


def render(results, plot_name):
    w = Markdown()
    s = results.get("summary") or {}
    prov = results.get("provenance") or {}
    rt = results.get("realtime") or {}
    w("# Palpation replay `%s`" % results.get("study"))
    w("")
    w("Scene `%s` (%s tool), organ `%s`, organ atlas `%s`; git %s. The real-time run (virtual clock, %s s, %s models) "
      "gave a force at %s ticks; %s contacts were verified against the reference FEM of the whole organ (%s "
      "mesh levels%s), over %s ticks." % (
          results.get("scene"), results.get("contact_condition"), os.path.basename(results.get("organ_file") or ""),
          os.path.basename(results.get("organ_atlas") or "") or "none", prov.get("git"), fmt(rt.get("duration_s"), "%.1f"),
          rt.get("models"), rt.get("frames_with_model"), s.get("verified_contacts"), get(results, "params", "levels"),
          ", Richardson" if (get(results, "params", "levels") or 0) >= 3 else "", s.get("verified_frames")))
    w("")
    w("| measure | value |")
    w("|---|---|")
    w("| force error, relative L2 over all verified ticks | %s |" % pct(s.get("force_error_l2")))
    w("| force error, RMS over the contacts of each contact's relative L2 | %s |" % pct(s.get("force_error_rms_over_contacts")))
    w("| largest force error | %s mN |" % fmt(None if s.get("force_error_max_N") is None else 1e3 * s["force_error_max_N"], "%.3f"))
    w("| largest relative error (ticks with \\|F_ref\\| >= %s mN) | %s |" % (
        fmt(None if s.get("relative_error_floor_N") is None else 1e3 * s["relative_error_floor_N"], "%.2f"),
        pct(s.get("force_error_max_relative"))))
    w("| largest angle between the forces | %s deg |" % fmt(s.get("force_angle_max_deg"), "%.2f"))
    w("| surface displacement error, relative L2 over the local vertices and all ticks | %s |" % pct(s.get("displacement_error_l2")))
    w("| reference's own error estimate, largest over the contacts | %s |" % pct(s.get("reference_uncertainty_max"), 3))
    w("| rebuilt K_t against the run's, largest relative difference | %s |" % fmt(s.get("rebuilt_stiffness_mismatch_max"), "%.2g"))
    timing = results.get("timing") or {}
    w("| time: real-time run, reference solves, total (MPI ranks) | %s s, %s s, %s s (%s) |" % (
        fmt(timing.get("realtime_s"), "%.1f"), fmt(timing.get("reference_s"), "%.1f"), fmt(timing.get("total_s"), "%.1f"),
        timing.get("mpi_ranks")))
    w("")
    if plot_name:
        w("![force over time](%s)" % plot_name)
        w("")
    w("## Per contact")
    w("")
    w("k = d·K d along the push direction d. The stiffness error is k_mfs / k_ref - 1; the force error is the relative "
      "L2 of F_mfs - F_ref over the contact's ticks; the displacement error is the relative L2 of the surface "
      "displacements at the local vertices (inside the local ball) over the contact's ticks. The reference's uncertainty stands beside "
      "every number.")
    w("")
    rows = []
    for c in results.get("contacts") or []:
        conv = c.get("reference_convergence") or {}
        levels = c.get("reference_levels") or [{}]
        rows.append([c.get("label"), c.get("reason"), fmt(c.get("adopted_s"), "%.3f"), c.get("frames"), c.get("exterior_used"),
                     fmt(c.get("axial_stiffness_mfs_N_per_m"), "%.4f"), fmt(c.get("axial_stiffness_reference_N_per_m"), "%.4f"),
                     pct(c.get("stiffness_error")), pct(c.get("force_error_l2")), pct(conv.get("relative_uncertainty"), 3),
                     pct(c.get("displacement_error_l2_over_ticks")), levels[-1].get("dofs"), c.get("solved_on_rank")])
    w.extend(table(["contact", "why built", "at [s]", "ticks", "exterior", "k_mfs [N/m]", "k_ref [N/m]", "stiffness error",
                    "force error", "ref. uncertainty", "displacement error", "dofs (finest)", "rank"], rows,
                   ["l", "l", "r", "r", "l", "r", "r", "r", "r", "r", "r", "r", "r"]))
    w("")
    w("### Surface displacements at each contact's deepest press")
    w("")
    w("The local vertices (inside the local ball). The difference split into one translation of the whole region "
      "(the mean difference: the organ moving as a body, which a field confined to the local ball cannot show) and "
      "the rest.")
    w("")
    rows = []
    for c in results.get("contacts") or []:
        mean = c.get("displacement_mean_difference_m") or [None] * 3
        rows.append([c.get("label"), fmt(None if c.get("deepest_press_m") is None else 1e3 * c["deepest_press_m"], "%.2f"),
                     "%s / %s" % (c.get("displacement_vertices_found"), c.get("displacement_vertices")),
                     pct(c.get("displacement_error_l2")),
                     " ".join(fmt(None if x is None else 1e3 * x, "%.3f") for x in mean),
                     pct(c.get("displacement_error_l2_without_mean"))])
    w.extend(table(["contact", "press [mm]", "vertices compared", "error", "mean difference [mm]", "error without the mean"],
                   rows, ["l", "r", "r", "r", "r", "r"]))
    w("")
    w("## Worst ticks")
    w("")
    w.extend(table(["time [s]", "contact", "error [mN]", "relative"],
                   [[fmt(f.get("time_s"), "%.3f"), "model%s" % f.get("model_id"), fmt(1e3 * f.get("error_N", 0), "%.3f"),
                     pct(f.get("relative_error"))] for f in results.get("worst_frames") or []], ["r", "l", "r", "r"]))
    w("")
    w("Files: `frames.csv` (every verified tick), `contacts.csv`, `paraview/contacts.pvd` (the organ surface with both "
      "displacement fields and their difference at each contact's deepest press), `paraview/*_reference_*.vtu` (the "
      "reference's unit fields on the finest mesh), `realtime/` (the real-time run's summary and force history).")
    return w.text()


def write(output_dir, plots=True):
    """Reads output_dir/results.json, writes report.md (and the plot); returns the report's path."""
    results = load_json(output_dir)
    plot_name = None
    if plots:
        plot_name = "force_over_time.png"
        plot(results, os.path.join(output_dir, plot_name))
    return write_report(output_dir, render(results, plot_name))
