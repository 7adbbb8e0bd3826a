#!/usr/bin/env python3
"""The library folders depend on each other in one direction only:

    geometry  <-  meshes
    geometry  <-  realtime
    geometry, meshes  <-  reference_fem
    meshes, reference_fem, realtime  <-  studies

deal.II stays inside reference_fem/, and inside realtime/ no two folders include each other. This check fails, naming the file and line, when a source
file includes a header of a folder it must not depend on, or when a folder's CMakeLists.txt
links a library target it must not depend on.

Usage: check_dependencies.py <repository root>
       check_dependencies.py --self-test   (the check finds each kind of violation)
"""
import pathlib
import re
import sys

# Folder -> the libraries it must not use: their headers (include/touchstone/<x>/) and their CMake
# targets (touchstone::<x>) have the same name.
FORBIDDEN = {
    "geometry": ["realtime", "meshes", "fem", "studies"],
    "meshes": ["realtime", "fem", "studies"],
    "realtime": ["meshes", "fem", "studies"],
    "reference_fem": ["realtime", "studies"],
}
DEAL_II_ALLOWED = {"reference_fem"}

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]')
LINK = re.compile(r"touchstone::(\w+)")


def main(root: pathlib.Path) -> int:
    problems = []
    folders = set(FORBIDDEN) | {"studies"}
    for folder in sorted(folders):
        base = root / folder
        if not base.is_dir():
            problems.append(f"{folder}/: the folder is missing")
            continue
        for path in sorted(base.rglob("*")):
            if path.suffix not in {".hpp", ".cpp", ".h"}:
                continue
            for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
                match = INCLUDE.match(line)
                if not match:
                    continue
                header = match.group(1)
                where = f"{path.relative_to(root)}:{number}"
                if header.startswith("deal.II/") and folder not in DEAL_II_ALLOWED:
                    problems.append(f"{where}: includes deal.II ({header}); deal.II stays inside reference_fem/")
                for other in FORBIDDEN.get(folder, []):
                    if header.startswith(f"touchstone/{other}/"):
                        problems.append(f"{where}: {folder}/ must not depend on {other} (includes {header})")
        cmake = base / "CMakeLists.txt"
        if cmake.is_file():
            for number, line in enumerate(cmake.read_text(encoding="utf-8").splitlines(), start=1):
                if line.lstrip().startswith("#"):
                    continue
                for target in LINK.findall(line):
                    if target in FORBIDDEN.get(folder, []):
                        problems.append(f"{cmake.relative_to(root)}:{number}: {folder}/ must not link touchstone::{target}")
    problems += mutual_includes(root / "realtime", "touchstone/realtime/")
    for problem in problems:
        print(problem)
    print(f"{len(problems)} forbidden dependencies" if problems else "dependency directions: ok")
    return 1 if problems else 0


def mutual_includes(library: pathlib.Path, prefix: str) -> list:
    """Inside one library, no two of its folders (realtime/mfs, realtime/runtime, …) may include
    each other: one of them has to sit below the other."""
    edges = {}
    for path in sorted(library.rglob("*")):
        if path.suffix not in {".hpp", ".cpp", ".h"}:
            continue
        # include/touchstone/realtime/<folder>/… or src/<folder>/…
        parts = path.relative_to(library).parts
        depth = 3 if parts[0] == "include" else 1
        if len(parts) <= depth + 1:
            continue
        folder = parts[depth]
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            match = INCLUDE.match(line)
            if match and match.group(1).startswith(prefix):
                rest = match.group(1)[len(prefix):].split("/")
                if len(rest) > 1 and rest[0] != folder:
                    edges.setdefault((folder, rest[0]), f"{path.relative_to(library.parent)}:{number}")
    return [f"{where}: {a}/ includes {b}/ and {edges[(b, a)]} includes back: the two folders depend on each other"
            for (a, b), where in sorted(edges.items()) if (b, a) in edges and a < b]


def self_test() -> int:
    """A tree with one violation of each kind: every one must be reported."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        root = pathlib.Path(tmp)
        files = {
            "geometry/src/a.cpp": '#include "touchstone/realtime/mfs/x.hpp"\n',
            "meshes/src/b.cpp": '#include "touchstone/realtime/geometry.hpp"\n',
            "realtime/src/c.cpp": "#include <deal.II/base/point.h>\n",
            "reference_fem/src/d.cpp": '#include "touchstone/studies/config.hpp"\n',
            "meshes/CMakeLists.txt": "target_link_libraries(m PUBLIC touchstone::realtime)\n",
            "studies/src/e.cpp": '#include "touchstone/realtime/mfs/x.hpp"\n',  # allowed
            "realtime/src/haptics/f.cpp": '#include "touchstone/realtime/runtime/y.hpp"\n',
            "realtime/include/touchstone/realtime/runtime/y.hpp": '#include "touchstone/realtime/haptics/z.hpp"\n',
        }
        for name, text in files.items():
            (root / name).parent.mkdir(parents=True, exist_ok=True)
            (root / name).write_text(text, encoding="utf-8")
        import io
        import contextlib

        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            status = main(root)
        text = out.getvalue()
        expected = ["geometry/src/a.cpp:1", "meshes/src/b.cpp:1", "realtime/src/c.cpp:1",
                    "reference_fem/src/d.cpp:1", "meshes/CMakeLists.txt:1",
                    "haptics/ includes runtime/", "6 forbidden dependencies"]
        missing = [e for e in expected if e not in text]
        if status != 1 or missing or "studies/src/e.cpp" in text:
            print(text)
            print(f"self-test failed: status {status}, not reported: {missing}")
            return 1
    print("self-test: every kind of violation is reported")
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 2 and sys.argv[1] == "--self-test":
        sys.exit(self_test())
    if len(sys.argv) != 2:
        print(__doc__)
        sys.exit(2)
    sys.exit(main(pathlib.Path(sys.argv[1])))
