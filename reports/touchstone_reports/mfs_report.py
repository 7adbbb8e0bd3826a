"""A short report of a `touchstone mfs` run (an MFS sweep without reference): every case's force,
stiffness and build time. Errors against the FEM are the study runner's (`touchstone study`).

Reads OUTPUT_DIR/results.json, writes OUTPUT_DIR/report.md (no plots, no matplotlib needed).
"""
from .common import Markdown, fmt, get, load_json, mn, seconds, table, write_report


def render(results):
    w = Markdown()
    prov = results.get("provenance") or {}
    organ = results.get("organ") or {}
    cases = results.get("cases") or []
    ok = [c for c in cases if c.get("status") == "ok"]
    w("# MFS study `%s`" % results.get("study"))
    w("")
    w("From `results.json` (git %s, %s build). Organ %s, %s triangles. %d case%s, %d ok. Forces in mN along the tool "
      "direction (the engine's haptic force); no reference here: `touchstone study` pairs these cases with the FEM. "
      "Flags: what a case says about its own accuracy (the force extractions disagree, supports grew, ill "
      "conditioned, implausible stiffness, unconverged against the previous N)."
      % (prov.get("git"), prov.get("build_type"), organ.get("path"), organ.get("triangles"), len(cases),
         "" if len(cases) == 1 else "s", len(ok)))
    w("")
    w.extend(table(["case", "N", "F [mN]", "k*", "stiffness [N/m]", "build", "status", "flags"],
                   [["`%s`" % c.get("id"), get(c, "params", "node_count"), mn(get(c, "qoi", "axial_force_N")),
                     fmt(get(c, "qoi", "k_star"), "%.4f"), fmt(get(c, "qoi", "stiffness_N_per_m"), "%.4g"),
                     seconds(get(c, "time_s", "build")), c.get("status"),
                     ", ".join(get(c, "accuracy", "flags") or []) or "-"] for c in cases],
                   ["l", "r", "r", "r", "r", "r", "l", "l"]))
    return w.text()


def write(output_dir):
    """Reads output_dir/results.json, writes report.md; returns its path."""
    return write_report(output_dir, render(load_json(output_dir)))
