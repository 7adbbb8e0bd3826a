"""A `touchstone study` killed (SIGKILL) during an FEM solve and again during the MFS cases,
then run again, gives the numbers of an uninterrupted run, and leaves no cache entry or output
file that does not read back. A full disk (a file-size limit) ends in exit status 1 with an
error naming the file, and what was done before stays usable: the run after it gives the same
numbers. An output folder that cannot be made is refused before any work (exit status 2, the
path named, nothing written).

Usage: check_kill_resume.py <touchstone binary> <study.toml> <scratch dir>"""
import json
import os
import pathlib
import resource
import shutil
import signal
import subprocess
import sys
import time

binary, study, scratch = str(pathlib.Path(sys.argv[1]).resolve()), pathlib.Path(sys.argv[2]).resolve(), pathlib.Path(sys.argv[3]).resolve()
shutil.rmtree(scratch, ignore_errors=True)
scratch.mkdir(parents=True)
failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
        print("FAIL:", message)


def run(folder, limit_bytes=None):
    """Runs the study in `folder` (its cache is folder/.cache) to the end."""
    folder.mkdir(exist_ok=True)

    def limit():
        if limit_bytes is not None:
            # Ignored SIGXFSZ: a write beyond the limit fails with EFBIG, as on a full disk.
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    # Under the limit, MPI keeps its start-up data in memory and talks over TCP: its shared-memory
    # files would meet the limit before the study's own files do.
    environment = dict(os.environ, PMIX_MCA_gds="hash", OMPI_MCA_btl="self,tcp") if limit_bytes else None
    return subprocess.run([binary, "study", str(study), "--out", "out", "--no-report"], cwd=folder, env=environment,
                          capture_output=True, text=True, preexec_fn=limit, timeout=600)


def run_and_kill(folder, after_line, delay_s):
    """Starts the study in `folder` and kills it `delay_s` after a line containing `after_line`."""
    folder.mkdir(exist_ok=True)
    process = subprocess.Popen([binary, "study", str(study), "--out", "out", "--no-report"], cwd=folder,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 300
    for line in process.stdout:
        if after_line in line or time.time() > deadline:
            break
    time.sleep(delay_s)
    process.send_signal(signal.SIGKILL)
    process.wait()
    return process.returncode


def numbers(folder):
    """What the study computed: the reference force and every case's force and errors."""
    results = json.loads((folder / "out" / "results.json").read_text())
    cases = {}
    for case in results["cases"]:
        cases[case["id"]] = {"status": case["status"], "qoi": case.get("qoi"),
                             "error": {k: v for k, v in (case.get("error") or {}).items()}}
    return {"reference": results["reference_summary"]["axial_force_N"], "cases": cases}


def unreadable_files(folder):
    """Every JSON and VTU file under `folder` that does not parse (a VTU must be whole XML)."""
    bad = []
    for path in folder.rglob("*"):
        if path.suffix == ".json":
            try:
                json.loads(path.read_text())
            except (ValueError, UnicodeDecodeError) as error:
                bad.append(f"{path}: {error}")
        elif path.suffix in (".vtu", ".pvtu", ".pvd"):
            text = path.read_bytes()
            if not text.rstrip().endswith(b">") or b"</VTKFile>" not in text[-200:]:
                bad.append(f"{path}: not a whole VTK XML file")
    return bad


def cache_entries(folder):
    return sorted(p.parent.name for p in (folder / ".cache").rglob("case.json"))


# The uninterrupted run.
whole = scratch / "uninterrupted"
result = run(whole)
check(result.returncode == 0, f"the uninterrupted run failed: {result.stderr}")
expected = numbers(whole)
levels = len(cache_entries(whole))
print(f"uninterrupted: reference {expected['reference']:.6e} N, {len(expected['cases'])} cases, {levels} cached levels")

# Killed while the finest FEM level is being solved (the first level is done and cached).
killed = scratch / "killed"
run_and_kill(killed, "[1/", 2.0)
check(len(cache_entries(killed)) == levels - 1,
      f"the kill was meant to land in the last FEM level: {len(cache_entries(killed))} of {levels} levels cached")
check(not (killed / "out" / "results.json").exists(), "results.json exists after a kill during the FEM solve")
check(unreadable_files(killed) == [], f"after the kill in the FEM solve: {unreadable_files(killed)}")
# Killed again, during the MFS cases (the FEM reference is complete by then).
result = run_and_kill(killed, "FEM reference ", 1.0)
check(len(cache_entries(killed)) == levels, f"after the kill in the MFS cases: {len(cache_entries(killed))} of {levels} levels cached")
check(not (killed / "out" / "results.json").exists(), "results.json exists after a kill during the MFS cases")
check(unreadable_files(killed) == [], f"after the kill in the MFS cases: {unreadable_files(killed)}")
result = run(killed)
check(result.returncode == 0, f"the run after the kills failed: {result.stderr}")
check(numbers(killed) == expected, "the run after the kills differs from the uninterrupted run")
check(unreadable_files(killed) == [], f"after the resumed run: {unreadable_files(killed)}")

# A full disk: every file is limited to 64 KiB, so the mesh cache's first mesh cannot be written.
full = scratch / "full_disk"
result = run(full, limit_bytes=64 * 1024)
print(f"full disk: exit {result.returncode}: {result.stderr.strip()[-300:]}")
check(result.returncode == 1, f"a full disk gave exit status {result.returncode}, not 1")
check("cannot write '.cache/touchstone/meshes/" in result.stderr and ".msh'" in result.stderr,
      f"the full-disk error does not name the file it could not write: {result.stderr.strip()[-300:]}")
check(not list(full.rglob("*.partial*")), f"partial files left behind: {list(full.rglob('*.partial*'))}")
check(unreadable_files(full) == [], f"after the full disk: {unreadable_files(full)}")
result = run(full)
check(result.returncode == 0, f"the run after the full disk failed: {result.stderr}")
check(numbers(full) == expected, "the run after the full disk differs from the uninterrupted run")

# An output folder that cannot be made (its parent is a file; a root user writes anywhere else).
blocked = scratch / "blocked"
blocked.mkdir()
(blocked / "file").write_text("not a folder\n")
result = subprocess.run([binary, "study", str(study), "--out", "file/out", "--no-report"], cwd=blocked,
                        capture_output=True, text=True, timeout=600)
print(f"unwritable output: exit {result.returncode}: {result.stderr.strip()[-300:]}")
check(result.returncode == 2, f"an output folder that cannot be made gave exit status {result.returncode}, not 2")
check("file/out" in result.stderr, f"the error does not name the output folder: {result.stderr.strip()[-300:]}")
check(not (blocked / ".cache").exists(), "work was started (an FEM cache written) for an output folder that cannot be made")

if not failures:
    shutil.rmtree(scratch, ignore_errors=True)
sys.exit(1 if failures else 0)
