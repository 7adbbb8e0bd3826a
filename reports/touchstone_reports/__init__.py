"""Touchstone's reports: every report.md (and its PNG plots) is written here from the JSON the C++
programs write. The C++ side writes data only.

    PYTHONPATH=<folder holding touchstone_reports> /usr/bin/python3 -m touchstone_reports KIND OUTPUT_DIR

KIND is one of `study`, `collision`, `fem`, `mfs`, `sim`, `replay` (see `__main__.py`).
"""

KINDS = ("study", "collision", "fem", "mfs", "sim", "replay")
