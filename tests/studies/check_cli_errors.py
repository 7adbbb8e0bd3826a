"""Bad command lines and configs get a named error and a non-zero exit status, before anything is
written: each case runs `touchstone` and checks the status, a text in stderr and which files exist.
Usage: check_cli_errors.py <touchstone binary> <source dir> <scratch dir>"""
import pathlib
import shutil
import subprocess
import sys

binary, source, scratch = sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3])
shutil.rmtree(scratch, ignore_errors=True)
scratch.mkdir(parents=True)
configs = source / "studies" / "configs"

# A small MFS study; each case below changes one key.
MFS = """study = "cli_check"
[geometry]
benchmark = "B2"
body_radius = "50 mm"
tool_radius = "2.5 mm"
[tool]
depth = "{depth}"
[sprinkling]
node_count = {counts}
local_radius = "{local_radius}"
"""


def mfs_config(name, depth="0.25 mm", counts="[34]", local_radius="12.5 mm"):
    path = scratch / f"{name}.toml"
    path.write_text(MFS.format(depth=depth, counts=counts, local_radius=local_radius))
    return str(path)


failures = []


def check(name, args, status, text, absent=()):
    result = subprocess.run([binary, *args], capture_output=True, text=True, timeout=600)
    ok = (result.returncode == status if status is not None else result.returncode != 0) and text in result.stderr
    for path in absent:
        if pathlib.Path(path).exists():
            ok = False
            print(f"{name}: {path} was written")
    print(f"{'ok  ' if ok else 'FAIL'} {name}: exit {result.returncode}, stderr: {result.stderr.strip()[:200]}")
    if not ok:
        failures.append(name)


check("unknown subcommand", ["frobnicate"], 2, "unknown subcommand 'frobnicate'")
scene = str(configs / "scenes" / "palpation.toml")
check("sim --duration -5", ["sim", scene, "--duration", "-5"], None, "must be a finite number of seconds >= 0")
check("sim --duration nan", ["sim", scene, "--duration", "nan"], None, "must be a finite number of seconds >= 0")
out = scratch / "only"
check("study --only nomatch", ["study", str(configs / "ci_accuracy.toml"), "--only", "nomatch", "--out", str(out)], 1,
      "--only matches no MFS case", absent=[out])
out = scratch / "accept"
check("study accept without [ci]", ["study", "accept", str(configs / "hemisphere.toml"), "--out", str(out)], 1,
      "[ci] baseline is not set", absent=[out])
out = scratch / "depth"
check("mfs depth beyond L/2", ["mfs", mfs_config("depth", depth="1 m"), "--out", str(out)], 1, "tool.depth_m",
      absent=[out / "config.resolved.toml"])
out = scratch / "twice"
check("mfs node count twice", ["mfs", mfs_config("twice", counts="[34, 60, 34]"), "--out", str(out)], 1,
      "node_count lists 34 twice", absent=[out / "config.resolved.toml"])
out = scratch / "zero_l"
check("mfs zero local radius", ["mfs", mfs_config("zero_l", local_radius="0 mm"), "--out", str(out)], 1,
      "local_radius", absent=[out / "config.resolved.toml"])

# `mesh --out` into a folder that does not exist yet.
out = scratch / "m0"
result = subprocess.run([binary, "mesh", str(source / "tests" / "reference_fem" / "tiny_b2.toml"), "--refinement", "0",
                         "--out", str(out)], capture_output=True, text=True, timeout=600)
meshes = list(out.glob("*.msh")) if out.exists() else []
print(f"{'ok  ' if result.returncode == 0 and meshes else 'FAIL'} mesh --out new folder: exit {result.returncode}, "
      f"{len(meshes)} mesh file(s); {result.stderr.strip()[:200]}")
if result.returncode != 0 or not meshes:
    failures.append("mesh --out new folder")

sys.exit(f"{len(failures)} failed: {', '.join(failures)}" if failures else 0)
