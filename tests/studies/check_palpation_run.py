"""The shipped palpation scene runs headless for 60 s with the scripted device. Runs
`touchstone sim studies/configs/scenes/palpation.toml` on real threads and checks its summary.json: the
run lasted the full minute, the haptic loop's p99 lateness and missed deadlines are reported
(and printed against the 1 kHz loop's timing targets), the palpations touched the organ with
the model ready or faded in, the safety filter never intervened on this benign
trajectory, and the ParaView time series opens with VTK's XML readers.
Usage: check_palpation_run.py <touchstone binary> <source dir> <output dir>"""
import json
import pathlib
import subprocess
import sys
import xml.etree.ElementTree as ET

import vtk

binary, source, out = sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3])
scene = source / "studies" / "configs" / "scenes" / "palpation.toml"
subprocess.run([binary, "sim", str(scene), "--out", str(out)], check=True)
summary = json.loads((out / "summary.json").read_text())
failures = []


def check(condition, message):
    print(("ok   " if condition else "FAIL ") + message)
    if not condition:
        failures.append(message)


haptic = summary["loops"]["haptic"]
check(summary["end_reason"] == "duration", f"ran until the duration (end: {summary['end_reason']})")
check(abs(summary["duration_s"] - 60.0) < 0.01, f"60 s of run time ({summary['duration_s']:.3f} s)")
check(haptic["ticks"] + haptic["skipped_deadlines"] >= 59990, f"~60,000 haptic ticks ({haptic['ticks']} + {haptic['skipped_deadlines']} skipped)")
for key in ("lateness_p50_s", "lateness_p99_s", "lateness_max_s", "late_ticks", "late_fraction", "skipped_deadlines"):
    check(key in haptic, f"haptic loop reports {key}")
# The 1 kHz loop's timing targets, printed, not asserted: on a shared CI machine the load, not
# the code, decides whether they are met.
print(f"     haptic lateness p99 {haptic['lateness_p99_s'] * 1e6:.1f} us (target <= 50 us), "
      f"late > 0.5 ms {100 * haptic['late_fraction']:.3f} % (target <= 0.2 %), max {haptic['lateness_max_s'] * 1e6:.0f} us; "
      f"{summary['haptic_thread']['note']}")
work = summary["work"]
check(work["contacts"] >= summary["palpations"], f"every palpation touched ({work['contacts']} contacts, {summary['palpations']} palpations)")
check(work["model_build_failures"] == 0, "no model build failed")
check(summary["safety"]["interventions"] == 0, f"no safety intervention on a benign trajectory ({summary['safety']})")
check(0.05 < summary["forces"]["max_force_N"] < 3.0, f"a palpation force, below the clamp ({summary['forces']['max_force_N']:.3f} N)")
check(work["surface_updates"] > 0 and work["vertices_written"] < work["surface_updates"] * work["organ_vertices"] / 4,
      "only local vertices moved")
# The time series: both PVDs parse, every dataset they list opens.
series = summary["time_series"]
for key in ("organ_pvd", "tool_pvd"):
    pvd = pathlib.Path(series[key])
    datasets = ET.parse(pvd).getroot().findall("./Collection/DataSet")
    check(len(datasets) == series["frames_written"] and len(datasets) >= 290, f"{pvd.name}: {len(datasets)} timesteps")
    for dataset in datasets[:: max(1, len(datasets) // 10)]:
        reader = vtk.vtkXMLPolyDataReader()
        reader.SetFileName(str(pvd.parent / dataset.get("file")))
        reader.Update()
        check(reader.GetOutput().GetNumberOfPoints() > 0, f"{dataset.get('file')} opens")
sys.exit(1 if failures else 0)
