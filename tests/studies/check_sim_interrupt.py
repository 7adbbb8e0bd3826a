"""Ctrl-C ends `touchstone sim` cleanly: SIGINT a run of the palpation scene (a minute long) after
a few seconds; it must exit 0 within a second or two, with end_reason "stopped" and its summary
written.
Usage: check_sim_interrupt.py <touchstone binary> <source dir> <output dir>"""
import json
import pathlib
import signal
import subprocess
import sys
import time

binary, source, out = sys.argv[1], pathlib.Path(sys.argv[2]), pathlib.Path(sys.argv[3])
scene = source / "studies" / "configs" / "scenes" / "palpation.toml"
process = subprocess.Popen([binary, "sim", str(scene), "--out", str(out)], stdout=subprocess.PIPE, text=True)
deadline = time.time() + 120
while time.time() < deadline and "sim palpation:" not in (line := process.stdout.readline()):
    if process.poll() is not None:
        sys.exit(f"touchstone sim ended before the run started (exit {process.returncode})")
time.sleep(3.0)
sent = time.time()
process.send_signal(signal.SIGINT)
try:
    process.communicate(timeout=30)
except subprocess.TimeoutExpired:
    process.kill()
    sys.exit("touchstone sim did not stop within 30 s of SIGINT")
elapsed = time.time() - sent
summary = json.loads((out / "summary.json").read_text())
print(f"exit {process.returncode}, stopped {elapsed:.2f} s after SIGINT, end_reason {summary['end_reason']!r}, "
      f"run {summary['duration_s']:.2f} s")
ok = process.returncode == 0 and summary["end_reason"] == "stopped" and summary["duration_s"] < 30 and elapsed < 10
sys.exit(0 if ok else 1)
