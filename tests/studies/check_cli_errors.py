"""Bad command lines and configs get a named error and exit status 2 before anything is written;
a run that fails after starting exits 1. Each case runs `touchstone` in a scratch folder and checks
the status, a text in stderr (the key or value it names) and that nothing was written: neither
the output folder nor the FEM cache. `--table` prints the bad-number matrix as the README's table.
Usage: check_cli_errors.py <touchstone binary> <source dir> <scratch dir> [--table]"""
import os
import pathlib
import re
import shutil
import subprocess
import sys

binary = str(pathlib.Path(sys.argv[1]).resolve())
source, scratch = pathlib.Path(sys.argv[2]).resolve(), pathlib.Path(sys.argv[3]).resolve()
print_table = "--table" in sys.argv[4:]
shutil.rmtree(scratch, ignore_errors=True)
scratch.mkdir(parents=True)
configs = source / "studies" / "configs"
BAD_INPUT = 2

failures = []


def check(name, args, status, text, absent=(), cwd=None, timeout=600):
    try:
        result = subprocess.run([binary, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd)
    except subprocess.TimeoutExpired:
        print(f"FAIL {name}: no answer within {timeout} s")
        failures.append(name)
        return False
    ok = result.returncode == status and text in result.stderr
    for path in absent:
        if pathlib.Path(path).exists():
            ok = False
            print(f"{name}: {path} was written")
    print(f"{'ok  ' if ok else 'FAIL'} {name}: exit {result.returncode}, stderr: {result.stderr.strip()[-220:]}")
    if not ok:
        failures.append(name)
    return ok


# --- Command lines -------------------------------------------------------------------------------
check("unknown subcommand", ["frobnicate"], BAD_INPUT, "unknown subcommand 'frobnicate'")
scene = str(configs / "scenes" / "palpation.toml")
check("sim --duration -5", ["sim", scene, "--duration", "-5"], BAD_INPUT, "must be a finite number of seconds >= 0")
check("sim --duration nan", ["sim", scene, "--duration", "nan"], BAD_INPUT, "must be a finite number of seconds >= 0")
check("mfs without a config", ["mfs"], BAD_INPUT, "config is required")
out = scratch / "only"
check("study --only nomatch", ["study", str(configs / "ci_accuracy.toml"), "--only", "nomatch", "--out", str(out)],
      BAD_INPUT, "--only matches no MFS case", absent=[out])
out = scratch / "accept"
check("study accept without [ci]", ["study", "accept", str(configs / "hemisphere.toml"), "--out", str(out)], BAD_INPUT,
      "[ci] baseline is not set", absent=[out])

# --- A config that is a device or a named pipe: read forever or blocked on, were it opened -------
fifo = scratch / "pipe.toml"
os.mkfifo(fifo)
for command in ("mesh", "fem", "mfs", "study", "atlas", "sim", "collision"):
    for path in ("/dev/zero", str(fifo)):
        out = scratch / f"special_{command}"
        check(f"{command} {path}", [command, path, "--out", str(out)], BAD_INPUT, "device, pipe or socket, not a regular file",
              absent=[out], timeout=60)

# --- Command-line paths: --out that is a file, a recording to replay that is a pipe ------------
a_file = scratch / "a_file"
a_file.write_text("not a folder\n")
for command, config in [("fem", "b2_paper_size.toml"), ("mfs", "mfs_b3_enriched.toml"), ("study", "ci_accuracy.toml"),
                        ("atlas", "atlas_hemisphere.toml"), ("collision", "collision_table1.toml"), ("sim", "scenes/palpation.toml")]:
    check(f"{command} --out a file", [command, str(configs / config), "--out", str(a_file)], BAD_INPUT,
          f"'{a_file}' exists and is not a folder", timeout=60)
# Under a file, no output folder can be made: refused before the work (the FEM solved and then
# failed to write its results here).
under_a_file = a_file / "out"
for command, config in [("fem", "b2_paper_size.toml"), ("mfs", "mfs_b3_enriched.toml"), ("study", "ci_accuracy.toml"),
                        ("atlas", "atlas_hemisphere.toml"), ("collision", "collision_table1.toml"), ("sim", "scenes/palpation.toml"),
                        ("mesh", "b2_paper_size.toml")]:
    check(f"{command} --out under a file", [command, str(configs / config), "--out", str(under_a_file)], BAD_INPUT,
          f"'{under_a_file}' cannot be made ('{a_file}' is not a folder)", timeout=60)
msh_folder = scratch / "msh_folder.msh"
msh_folder.mkdir()
for name, path, text in [("under a file", a_file / "m.msh", f"'{a_file}' is not a folder"),
                         ("a folder", msh_folder, "it is a folder")]:
    check(f"mesh --out a .msh {name}", ["mesh", str(configs / "b2_paper_size.toml"), "--refinement", "0", "--out", str(path)],
          BAD_INPUT, f"'{path}' cannot be written ({text}", timeout=60)
check("sim --replay a pipe", ["sim", scene, "--virtual", "--replay", str(fifo), "--out", str(scratch / "replay_pipe")], BAD_INPUT,
      "cannot be read (it is a device, pipe or socket, not a regular file)", absent=[scratch / "replay_pipe"], timeout=60)
# A file written when the work ends (a recording after the whole session, a geometry script after
# the meshes): a folder, a pipe or a missing folder is refused before the work, not after it.
for name, path, text in [("a folder", scratch, "it is a folder"), ("a pipe", fifo, "it is a device, pipe or socket"),
                         ("in a missing folder", scratch / "missing" / "rec.csv", f"no folder '{scratch / 'missing'}'")]:
    out = scratch / "record_out"
    check(f"sim --record {name}", ["sim", scene, "--virtual", "--record", str(path), "--out", str(out)], BAD_INPUT,
          f"'{path}' cannot be written ({text}", absent=[out], timeout=60)
    out = scratch / "geo_out"
    check(f"mesh --geo {name}", ["mesh", str(configs / "b2_paper_size.toml"), "--geo", str(path), "--out", str(out)], BAD_INPUT,
          f"'{path}' cannot be written ({text}", absent=[out], timeout=60)

# --- `surface check` of a surface whose coordinates overflow its sizes: the defect, never inf or nan
huge = scratch / "huge.obj"
huge.write_text("v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nv 0 0 1e300\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
result = subprocess.run([binary, "surface", "check", str(huge)], capture_output=True, text=True, timeout=60)
ok = (result.returncode == 2 and "coordinate beyond" in result.stdout and "overflow" in result.stdout
      and not re.search(r"\b(inf|nan)\b", result.stdout))
print(f"{'ok  ' if ok else 'FAIL'} surface check of 1e300 coordinates: exit {result.returncode}, stdout: {result.stdout.strip()[-220:]}")
if not ok:
    failures.append("surface check of 1e300 coordinates")

# --- An empty or near-empty config runs nothing on defaults: what defines the problem is required
for command, text, named in [
        ("fem", 'study = "empty"\n', "missing key 'material.youngs_modulus'"),
        ("mesh", 'study = "empty"\n[material]\nyoungs_modulus = "10 kPa"\npoisson_ratio = 0.45\n', "missing key 'geometry.tool_radius'"),
        ("mfs", "", "missing key 'geometry.body_radius'"),
        ("atlas", "", "missing key 'geometry.body_radius'"),
        ("sim", 'scene = "empty"\n', "missing key 'material.youngs_modulus'"),
        ("study", '[problem]\nbenchmark = "B3"\n', "missing key 'problem.body_radius'")]:
    folder = scratch / f"empty_{command}"
    folder.mkdir()
    (folder / "empty.toml").write_text(text)
    check(f"{command}: a near-empty config", [command, str(folder / "empty.toml"), "--out", str(folder / "out")], BAD_INPUT,
          named, absent=[folder / "out", folder / ".cache"], cwd=folder)

# --- Bad numbers at every entry: one key changed in a valid config per case ----------------------
# Base configs, each valid as written (every one is also run unchanged by other tests).
MFS = """study = "cli_check"
[geometry]
benchmark = "B2"
body_radius = "50 mm"
tool_radius = "2.5 mm"
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[tool]
depth = "0.25 mm"
[sprinkling]
node_count = [34]
local_radius = "12.5 mm"
"""
FEM = """study = "cli_check_fem"
[geometry]
benchmark = "B2"
body_radius = "50 mm"
tool_radius = "5 mm"
[material]
youngs_modulus = "10 kPa"
poisson_ratio = 0.45
[mesh]
edge_size = "2.5 mm"
size_growth = 0.8
max_size = "25 mm"
refinements = [0]
[tool]
depth = "0.5 mm"
[solver]
degree = 1
"""
STUDY = (configs / "ci_accuracy.toml").read_text().replace('config = "b3_reference.toml"',
                                                            f'config = "{configs / "b3_reference.toml"}"')
STUDY = re.sub(r'\[ci\].*?(?=\n\[mfs)', "", STUDY, flags=re.S)
ATLAS = (configs / "atlas_hemisphere.toml").read_text()
SCENE = (configs / "scenes" / "palpation.toml").read_text().replace(
    '"../atlases/stomach.json"', f'"{configs / "atlases" / "stomach.json"}"')
COLLISION = (configs / "collision_table1.toml").read_text()

BASES = {"mesh": FEM, "fem": FEM, "mfs": MFS, "study": STUDY, "atlas": ATLAS, "sim": SCENE, "collision": COLLISION}
EXTRA_ARGS = {"sim": ["--virtual", "--duration", "5"]}  # one palpation: 4.8 s

# --- A file the config names (an organ surface, an atlas) that is a pipe or a folder -------------
named_pipe = scratch / "organ.obj"
os.mkfifo(named_pipe)
folder_named = scratch / "atlas_folder"
folder_named.mkdir()
shipped_atlas = f'"{configs / "atlases" / "stomach.json"}"'
for command, base_text, text, path, named in [
        ("sim", '[organ]\nshape = "stomach"', '[organ]\nsurface = "{}"', named_pipe, "organ.surface"),
        ("sim", shipped_atlas, '"{}"', folder_named, "organ.atlas"),
        ("mfs", '[sprinkling]', '[organ]\nsurface = "{}"\n[sprinkling]', named_pipe, "organ.surface"),
        ("mfs", '[sprinkling]', '[organ]\natlas = "{}"\n[sprinkling]', folder_named, "organ.atlas")]:
    folder = scratch / f"named_file_{command}_{path.name}"
    folder.mkdir()
    base = BASES[command]
    if base_text not in base:
        sys.exit(f"check_cli_errors.py: '{base_text}' is not in the {command} base config (the shipped config changed?)")
    (folder / "bad.toml").write_text(base.replace(base_text, text.format(path), 1))
    reason = "it is a folder" if path.is_dir() else "it is a device, pipe or socket, not a regular file"
    check(f"{command}: {named} is {path.name}", [command, str(folder / "bad.toml"), "--out", str(folder / "out")], BAD_INPUT,
          f"{named}: cannot read '{path}' ({reason}", absent=[folder / "out"], timeout=60)


# class → subcommand → (text replaced, replacement, text the error must contain).
MATERIAL_READERS = ("mesh", "fem", "mfs", "study", "atlas", "sim")


def in_every_material_reader(old, new, named):
    return {command: (old, new, named) for command in MATERIAL_READERS}


E, NU = 'youngs_modulus = "10 kPa"', "poisson_ratio = 0.45"
CASES = {
    "E = NaN": in_every_material_reader(E, 'youngs_modulus = "nan kPa"', "youngs_modulus"),
    "E = Inf": in_every_material_reader(E, 'youngs_modulus = "inf kPa"', "youngs_modulus"),
    "E < 0": in_every_material_reader(E, 'youngs_modulus = "-10 kPa"', "youngs_modulus"),
    "E = 0": in_every_material_reader(E, 'youngs_modulus = "0 kPa"', "youngs_modulus"),
    "E = 1e200 Pa": in_every_material_reader(E, 'youngs_modulus = "1e200 Pa"', "youngs_modulus"),
    "ν = 0.5": in_every_material_reader(NU, "poisson_ratio = 0.5", "poisson_ratio"),
    "ν = NaN": in_every_material_reader(NU, "poisson_ratio = nan", "poisson_ratio"),
    "tool radius ≤ 0": {
        "mesh": ('tool_radius = "5 mm"', 'tool_radius = "-5 mm"', "tool_radius"),
        "fem": ('tool_radius = "5 mm"', 'tool_radius = "0 mm"', "tool_radius"),
        "mfs": ('tool_radius = "2.5 mm"', 'tool_radius = "0 mm"', "tool_radius"),
        "study": ('tool_radius = "2.5 mm"', 'tool_radius = "-2.5 mm"', "tool_radius"),
        "atlas": ('tool_radius = "2.5 mm"', 'tool_radius = "0 mm"', "tool_radius"),
        "sim": ('tip_radius = "2.5 mm"', 'tip_radius = "-2.5 mm"', "tip_radius"),
    },
    "body size NaN or ≤ 0": {
        "mesh": ('body_radius = "50 mm"', 'body_radius = "nan mm"', "body_radius"),
        "fem": ('body_radius = "50 mm"', 'body_radius = "0 mm"', "body_radius"),
        "mfs": ('body_radius = "50 mm"', 'body_radius = "inf mm"', "body_radius"),
        "study": ('body_radius = "50 mm"', 'body_radius = "-50 mm"', "body_radius"),
        "atlas": ('body_radius = "50 mm"', 'body_radius = "nan mm"', "body_radius"),
        "collision": ('hemisphere_radius = "50 mm"', 'hemisphere_radius = "0 mm"', "hemisphere_radius"),
    },
    "depth beyond the body": {
        "mesh": ('depth = "0.5 mm"', 'depth = "80 mm"', "tool.depth_m"),
        "fem": ('depth = "0.5 mm"', 'depth = "80 mm"', "tool.depth_m"),
        "mfs": ('depth = "0.25 mm"', 'depth = "1 m"', "tool.depth_m"),
        "study": ('depths = ["0.125 mm", "0.25 mm"]', 'depths = ["0.125 mm", "80 mm"]', "problem.depths"),
        "atlas": ('trace_depth = "0.1 mm"', 'trace_depth = "80 mm"', "trace_depth"),
        "sim": ('press_depth = "3 mm"', 'press_depth = "1 m"', "press_depth"),
    },
    "depth ≤ 0": {
        "mesh": ('depth = "0.5 mm"', 'depth = "nan mm"', "tool.depth"),
        "fem": ('depth = "0.5 mm"', 'depth = "-0.5 mm"', "depth_m"),
        "mfs": ('depth = "0.25 mm"', 'depth = "0 mm"', "tool.depth_m"),
        "study": ('depths = ["0.125 mm", "0.25 mm"]', 'depths = ["-0.125 mm"]', "problem.depths"),
        "atlas": ('trace_depth = "0.1 mm"', 'trace_depth = "0 mm"', "trace_depth"),
        "sim": ('press_depth = "3 mm"', 'press_depth = "-3 mm"', "press_depth"),
    },
    "empty list": {
        "mesh": ("refinements = [0]", "refinements = []", "refinements"),
        "fem": ("refinements = [0]", "refinements = []", "refinements"),
        "mfs": ("node_count = [34]", "node_count = []", "node_count"),
        "study": ('depths = ["0.125 mm", "0.25 mm"]', "depths = []", "depths"),
        "atlas": ('polar_angles = ["0 deg", "15 deg", "30 deg", "45 deg", "60 deg"]', "polar_angles = []", "polar_angles"),
        "collision": ("stomach_triangles = [500, 2500, 17000, 35000]   # J-shaped stomach, about 0.2 m\nhemisphere_triangles = [2500]",
                      "stomach_triangles = []\nhemisphere_triangles = []", "stomach_triangles and hemisphere_triangles are empty"),
    },
    "rate or count out of range": {
        "sim": ("haptic_hz = 1000", "haptic_hz = 1e9", "haptic_hz"),
        "collision": ("stomach_triangles = [500, 2500, 17000, 35000]", "stomach_triangles = [-500]", "stomach_triangles"),
        "mfs": ("node_count = [34]", "node_count = [0]", "node_count"),
    },
}

table = {}
for index, (case, per_command) in enumerate(CASES.items()):
    for command, (old, new, named) in per_command.items():
        base = BASES[command]
        if old not in base:
            sys.exit(f"check_cli_errors.py: '{old}' is not in the {command} base config (the shipped config changed?)")
        folder = scratch / f"{command}_{index}"
        folder.mkdir()
        config = folder / "bad.toml"
        config.write_text(base.replace(old, new, 1))
        out = folder / "out"
        args = [command, str(config), *EXTRA_ARGS.get(command, []), "--out", str(out)]
        ok = check(f"{command}: {case} ({new})", args, BAD_INPUT, named, absent=[out, folder / ".cache"], cwd=folder)
        table.setdefault(case, {})[command] = f"`{named}`" if ok else "**FAIL**"

# A run that fails after it started is not bad input: status 1 (every MFS case failing).
out = scratch / "all_fail"
(scratch / "all_fail.toml").write_text(MFS.replace('local_radius = "12.5 mm"', 'local_radius = "12.5 mm"\n[mls]\nmin_rcond = 0.99'))
result = subprocess.run([binary, "mfs", str(scratch / "all_fail.toml"), "--out", str(out)], capture_output=True, text=True,
                        timeout=600)
all_failed = result.returncode == 1 and (out / "results.json").exists()
print(f"{'ok  ' if all_failed else 'FAIL'} mfs in which every case fails: exit {result.returncode}, "
      f"results.json {'written' if (out / 'results.json').exists() else 'missing'}; {result.stderr.strip()[-200:]}")
if not all_failed:
    failures.append("mfs in which every case fails")

# `mesh --out` into a folder that does not exist yet.
out = scratch / "m0"
result = subprocess.run([binary, "mesh", str(source / "tests" / "reference_fem" / "tiny_b2.toml"), "--refinement", "0",
                         "--out", str(out)], capture_output=True, text=True, timeout=600, cwd=scratch)
meshes = list(out.glob("*.msh")) if out.exists() else []
print(f"{'ok  ' if result.returncode == 0 and meshes else 'FAIL'} mesh --out new folder: exit {result.returncode}, "
      f"{len(meshes)} mesh file(s); {result.stderr.strip()[:200]}")
if result.returncode != 0 or not meshes:
    failures.append("mesh --out new folder")
# The defaults a file leaves out are printed: tiny_b2.toml sets no size_exponent nor solver method.
printed = "does not set" in result.stdout and "mesh.size_exponent = 0.75" in result.stdout and "solver.method = " in result.stdout
print(f"{'ok  ' if printed else 'FAIL'} defaults filled in are printed: {result.stdout.strip()[:300]}")
if not printed:
    failures.append("defaults filled in are printed")

if print_table:
    commands = list(BASES)
    print("\n| bad value | " + " | ".join(f"`{c}`" for c in commands) + " |")
    print("|---|" + "---|" * len(commands))
    for case, row in table.items():
        print(f"| {case} | " + " | ".join(row.get(c, "—") for c in commands) + " |")

sys.exit(f"{len(failures)} failed: {', '.join(failures)}" if failures else 0)
