#!/usr/bin/python3
"""The study report, kept under its old name for callers that run this script by path:

    /usr/bin/python3 reports/make_report.py OUTPUT_DIR

is `python3 -m touchstone_reports study OUTPUT_DIR` (same output, same exit statuses).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from touchstone_reports.__main__ import main  # noqa: E402

if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.stderr.write("usage: make_report.py OUTPUT_DIR\n")
        sys.exit(1)
    sys.exit(main(["study", sys.argv[1]]))
