"""B4 run serially and under mpirun -np 2 (tests/studies/CMakeLists.txt): the same punch radii,
the same FEM forces (to the CG tolerance's reach, 1e-6 relative) and the same MFS forces and
errors, the MFS cases spread over both ranks.

Usage: check_point_tool_runs.py <serial output folder> <np2 output folder>
"""
import json
import math
import sys


def load(folder):
    with open(folder + "/results.json") as f:
        return json.load(f)


def main(serial_dir, parallel_dir):
    serial, parallel = load(serial_dir), load(parallel_dir)
    problems = [r["problems"][0] for r in (serial, parallel)]
    radii = [[p["punch_radius_m"] for p in q["punch_references"]] for q in problems]
    assert len(radii[0]) == 2, "two resolutions, two punches: %s" % radii[0]
    assert radii[0] == radii[1], "punch radii differ: %s vs %s" % tuple(radii)
    cases = [{c["id"]: c for c in r["cases"]} for r in (serial, parallel)]
    assert cases[0].keys() == cases[1].keys(), "case ids differ"
    compared = 0
    for case_id, a in cases[0].items():
        b = cases[1][case_id]
        fa, fb = a["qoi"].get("force_N"), b["qoi"].get("force_N")
        if a["model"] == "fem" and isinstance(fa, list):
            assert abs(fa[2] - fb[2]) <= 1e-6 * abs(fa[2]), "%s: %r vs %r" % (case_id, fa, fb)
            compared += 1
        if a["model"] == "mfs":
            assert a["status"] == b["status"] == "ok", case_id
            assert a["params"]["tip_spacing_m"] == b["params"]["tip_spacing_m"], case_id
            ea, eb = a["error"]["force_rel"], b["error"]["force_rel"]
            assert math.isfinite(ea) and abs(ea - eb) <= 1e-6 * abs(ea), "%s: %r vs %r" % (case_id, ea, eb)
            # The MFS case itself (seeded sprinkling) is the same on any rank: its force to the bit.
            assert a["qoi"]["force_N"] == b["qoi"]["force_N"], "%s: %r vs %r" % (case_id, a["qoi"]["force_N"], b["qoi"]["force_N"])
            compared += 1
    assert compared >= 6, "compared only %d cases" % compared
    # Under mpirun the MFS cases are spread over the ranks (case i on rank i mod 2).
    assert parallel.get("mfs_ranks") == 2, parallel.get("mfs_ranks")
    on_rank_1 = [c["id"] for c in parallel["cases"] if c["model"] == "mfs" and c.get("mpi_rank") == 1]
    assert on_rank_1, "no MFS case ran on rank 1"
    print("serial and np2 agree on %d cases; punch radii %s m" % (compared, radii[0]))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
