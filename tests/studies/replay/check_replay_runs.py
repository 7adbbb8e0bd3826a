"""The palpation replay run serially and under mpirun -np 2 (tests/studies/CMakeLists.txt).

Checks, on the two output folders:
- the same contacts, and under MPI both ranks solved some (the contacts were spread);
- every contact's reference tool stiffness equal to 1e-9 relative (each contact is solved on one
  rank alone, so the solves are the same; the CG tolerance is 1e-10);
- frames.csv: the reference force of every tick is push_only(K_ref (tip - c)) with the contact's
  K_ref and c from results.json (superposition applied as stated), and the two runs' rows agree;
- the real-time model rebuilt at each contact reproduces the run's K_t exactly.

Usage: check_replay_runs.py <serial output folder> <np2 output folder>
"""
import csv
import json
import sys


def load(folder):
    with open(folder + "/results.json") as f:
        results = json.load(f)
    with open(folder + "/frames.csv") as f:
        frames = list(csv.DictReader(f))
    return results, frames


def matvec(m, v):
    return [sum(m[r][c] * v[c] for c in range(3)) for r in range(3)]


def close(a, b, tol):
    scale = max(abs(x) for x in a + b) or 1.0
    return all(abs(x - y) <= tol * scale for x, y in zip(a, b))


def main(serial_dir, parallel_dir):
    (serial, serial_frames), (parallel, parallel_frames) = load(serial_dir), load(parallel_dir)
    a, b = serial["contacts"], parallel["contacts"]
    assert len(a) >= 2, "the tiny palpation should give at least two contacts, got %d" % len(a)
    assert [c["model_id"] for c in a] == [c["model_id"] for c in b], "the contacts differ"
    assert parallel["timing"]["mpi_ranks"] == 2, parallel["timing"]
    assert {c["solved_on_rank"] for c in b} == {0, 1}, "mpirun -np 2 did not spread the contacts"
    for x, y in zip(a, b):
        ka = sum(x["reference_stiffness_N_per_m"], [])
        kb = sum(y["reference_stiffness_N_per_m"], [])
        assert close(ka, kb, 1e-9), "%s: K_ref %r vs %r" % (x["label"], ka, kb)
    assert serial["summary"]["rebuilt_stiffness_mismatch_max"] == 0, serial["summary"]
    contacts = {c["model_id"]: c for c in a}
    assert len(serial_frames) == len(parallel_frames) > 100, (len(serial_frames), len(parallel_frames))
    for row, other in zip(serial_frames, parallel_frames):
        c = contacts[int(row["model_id"])]
        tip = [float(row["tip_%s_m" % k]) for k in "xyz"]
        u = [t - p for t, p in zip(tip, c["contact_point_m"])]
        f = matvec(c["reference_stiffness_N_per_m"], u)
        if sum(fi * di for fi, di in zip(f, c["direction"])) < 0:
            f = [0.0, 0.0, 0.0]
        got = [float(row["reference_%s_N" % k]) for k in "xyz"]
        assert close(got, f, 1e-12), "t = %s: reference %r, K_ref U = %r" % (row["time_s"], got, f)
        got_np2 = [float(other["reference_%s_N" % k]) for k in "xyz"]
        assert close(got, got_np2, 1e-9), "t = %s: serial %r, np2 %r" % (row["time_s"], got, got_np2)
    print("ok: %d contacts, %d ticks; serial = np2" % (len(a), len(serial_frames)))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
