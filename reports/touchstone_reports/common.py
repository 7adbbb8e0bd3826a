"""Shared pieces of every report: reading the results, number formatting, the Markdown table and
the atomic write of report.md.

Formatting contract (every report): relative errors are printed as 100 x the stored value with 2
decimals and a "%" sign, forces in mN with 4 decimals, times in µs, ms or s; a missing or
non-finite value prints as "n/a".
"""
import json
import math
import os


class ReportError(Exception):
    """A report cannot be written; `status` is the process exit status (2: missing input or
    missing matplotlib)."""

    def __init__(self, message, status=2):
        super().__init__(message)
        self.status = status


def load_json(output_dir, name="results.json"):
    """The JSON document `name` in `output_dir`; ReportError naming the file when it is missing
    or unreadable."""
    path = os.path.join(output_dir, name)
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError:
        raise ReportError("%s is missing (run the touchstone command that writes it first)" % path)
    except (OSError, ValueError) as error:
        raise ReportError("%s is unreadable: %s" % (path, error))


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend; ReportError when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        import sys

        raise ReportError("matplotlib is missing for %s; install it (apt-get install python3-matplotlib) "
                          "and run this report with /usr/bin/python3" % sys.executable)
    return plt


def finite(x):
    """True for an int or float (not a bool) that is finite."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def pct(x, digits=2):
    """A relative value as a percentage: 100 x, `digits` decimals ("0.0123" -> "1.23 %")."""
    return ("%.*f %%" % (digits, 100.0 * x)) if finite(x) else "n/a"


def mn(x):
    """A force [N] in mN, 4 decimals."""
    return ("%.4f" % (1e3 * x)) if finite(x) else "n/a"


def seconds(x):
    """A duration [s] in µs below 1 ms, in ms below 1 s, else in s."""
    if not finite(x):
        return "n/a"
    if x < 1e-3:
        return "%.1f µs" % (1e6 * x)
    if x < 1.0:
        return "%.2f ms" % (1e3 * x)
    return "%.2f s" % x


def fmt(x, spec, missing="n/a"):
    """`spec % x` for a finite number, else `missing`."""
    return (spec % x) if finite(x) else missing


def get(d, *path):
    """d[path[0]][path[1]]...; None when a key is absent or a level is not a dict."""
    for key in path:
        if not isinstance(d, dict) or key not in d:
            return None
        d = d[key]
    return d


def table(header, rows, align=None):
    """A Markdown table as lines: `header` cells, `rows` of cells, `align` one of "l"/"r" per
    column ("---" / "---:"; default all "---")."""
    align = align or ["l"] * len(header)
    lines = ["| " + " | ".join(header) + " |", "|" + "".join("---:|" if a == "r" else "---|" for a in align)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


class Markdown:
    """Collects report lines; `w(line)` appends one."""

    def __init__(self):
        self.lines = []

    def __call__(self, line=""):
        self.lines.append(line)

    def extend(self, lines):
        self.lines.extend(lines)

    def text(self):
        return "\n".join(self.lines) + "\n"


def write_report(output_dir, text, name="report.md"):
    """Writes `text` to output_dir/name atomically (a partial file, then a rename); returns the path."""
    path = os.path.join(output_dir, name)
    partial = path + ".partial"
    with open(partial, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(partial, path)
    return path


def save_figure(plt, fig, path, dpi=120):
    """Tight layout, write the PNG, close the figure."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
