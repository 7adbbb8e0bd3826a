"""`python3 -m touchstone_reports KIND OUTPUT_DIR [--no-plots] [--plot-note TEXT] [--quiet]`

Writes OUTPUT_DIR/report.md from the JSON in OUTPUT_DIR (results.json; summary.json for `sim`).
Exit status: 0 written, 1 usage error, 2 missing or unreadable input or missing matplotlib (the
message names what is missing).
"""
import argparse
import sys

from . import KINDS
from .common import ReportError


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m touchstone_reports",
                                     description="Write report.md (and PNG plots) from a touchstone output folder.")
    parser.add_argument("kind", choices=KINDS)
    parser.add_argument("output_dir")
    parser.add_argument("--no-plots", action="store_true",
                        help="collision, replay: write report.md without plots (no matplotlib needed)")
    parser.add_argument("--plot-note", default=None,
                        help="collision with --no-plots: why there are no plots (printed in the report)")
    parser.add_argument("--quiet", action="store_true", help="print only errors (not the report's path)")
    args = parser.parse_args(argv)
    try:
        if args.kind == "study":
            from . import study_report as module
            path = module.write(args.output_dir)
        elif args.kind == "collision":
            from . import collision_report as module
            path = module.write(args.output_dir, plots=not args.no_plots, plot_note=args.plot_note)
        elif args.kind == "fem":
            from . import fem_report as module
            path = module.write(args.output_dir)
        elif args.kind == "replay":
            from . import replay_report as module
            path = module.write(args.output_dir, plots=not args.no_plots)
        elif args.kind == "mfs":
            from . import mfs_report as module
            path = module.write(args.output_dir)
        else:
            from . import sim_report as module
            path = module.write(args.output_dir)
    except ReportError as error:
        sys.stderr.write("touchstone_reports %s: %s\n" % (args.kind, error))
        return error.status
    if not args.quiet:
        print("report: %s" % path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
