"""A short report of a `touchstone fem` run (the FEM reference study): every level's force and
error against its problem's Richardson extrapolation, and the convergence per problem.

Reads OUTPUT_DIR/results.json, writes OUTPUT_DIR/report.md (no plots, no matplotlib needed).
"""
from .common import Markdown, fmt, get, load_json, mn, pct, seconds, table, write_report


def case_row(c):
    """One case: id, model, dofs ("-" for the extrapolated and closed-form cases), F, k*, errors, time, status."""
    dofs = get(c, "mesh", "dofs")
    return ["`%s`" % c.get("id"), c.get("model"), "-" if dofs is None else dofs, mn(get(c, "qoi", "axial_force_N")),
            fmt(get(c, "qoi", "k_star"), "%.4f"), pct(get(c, "error", "force_rel")), pct(get(c, "error", "disp_rel_l2")),
            seconds(get(c, "time_s", "total")), c.get("status")]


def render(results):
    w = Markdown()
    prov = results.get("provenance") or {}
    w("# FEM reference study `%s`" % results.get("study"))
    w("")
    w("From `results.json` (git %s, %s build). Forces in mN along the tool direction; errors are 100 x the stored "
      "relative value against the problem's Richardson-extrapolated force (the finest level's with fewer "
      "than three levels)." % (prov.get("git"), prov.get("build_type")))
    w("")
    cases = results.get("cases") or []
    w.extend(table(["case", "model", "dofs", "F [mN]", "k*", "force error", "displacement error", "time", "status"],
                   [case_row(c) for c in cases],
                   ["l", "l", "r", "r", "r", "r", "r", "r", "l"]))
    w("")
    convergence = results.get("convergence") or []
    if convergence:
        w("## Convergence per problem")
        w("")
        w.extend(table(["problem", "levels", "extrapolated F [mN]", "observed order", "uncertainty", "asymptotic"],
                       [[p.get("problem"), len(p.get("levels") or []), mn(p.get("extrapolated_force_N")),
                         fmt(p.get("observed_order"), "%.2f"), pct(p.get("extrapolated_relative_uncertainty"), 3),
                         {True: "yes", False: "no"}.get(p.get("asymptotic"), p.get("note", "-"))] for p in convergence]))
        w("")
    return w.text()


def write(output_dir):
    """Reads output_dir/results.json, writes report.md; returns its path."""
    return write_report(output_dir, render(load_json(output_dir)))
