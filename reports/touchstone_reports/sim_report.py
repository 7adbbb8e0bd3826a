"""A short report of a `touchstone sim` run: the run, its loops' timing, forces and safety.

Reads OUTPUT_DIR/summary.json (what `touchstone sim` writes), writes OUTPUT_DIR/report.md (no
plots, no matplotlib needed).
"""
from .common import Markdown, fmt, get, load_json, pct, table, write_report


def microseconds(x):
    """A duration [s] in µs, 1 decimal."""
    return fmt(None if x is None else 1e6 * x, "%.1f µs")


def render(summary):
    w = Markdown()
    w("# Simulation `%s`" % summary.get("scene"))
    w("")
    w("From `summary.json`: %s clock, device %s, %s s, ended: %s, force mode %s; organ %s triangles." % (
        summary.get("clock"), summary.get("device"), fmt(summary.get("duration_s"), "%.2f"), summary.get("end_reason"),
        summary.get("force_mode"), summary.get("organ_triangles")))
    w("")
    rows = []
    for name in ("haptic", "model", "graphics"):
        loop = get(summary, "loops", name) or {}
        rows.append([name, loop.get("ticks", 0), microseconds(loop.get("lateness_p99_s")),
                     microseconds(loop.get("lateness_max_s")), pct(loop.get("late_fraction"), 3),
                     microseconds(loop.get("work_p99_s"))])
    w.extend(table(["loop", "ticks", "lateness p99", "lateness max", "late share", "work p99"], rows,
                   ["l", "r", "r", "r", "r", "r"]))
    w("")
    forces = summary.get("forces") or {}
    safety = summary.get("safety") or {}
    w("Largest force %s N; extrapolation error RMS %s N (max %s N); %s model switches (largest jump %s N); safety "
      "interventions %s of %s ticks; %s contacts." % (
          fmt(forces.get("max_force_N"), "%.4g"), fmt(forces.get("extrapolation_error_rms_N"), "%.3g"),
          fmt(forces.get("extrapolation_error_max_N"), "%.3g"), forces.get("model_switches"),
          fmt(forces.get("switch_jump_max_N"), "%.3g"), safety.get("interventions"), safety.get("ticks"),
          get(summary, "work", "contacts")))
    for note in summary.get("notes") or []:
        w("")
        w("- %s" % note)
    return w.text()


def write(output_dir):
    """Reads output_dir/summary.json, writes report.md; returns its path."""
    return write_report(output_dir, render(load_json(output_dir, "summary.json")))
