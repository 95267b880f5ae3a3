"""Two daemons' own time on one session step, alternated (docs/benchmarks.md,
"A mesh's step"): the FEM scene of python_steps.py (66,604 nodes, 1,776 on
the surfaces), a session on each daemon through the Python client, rounds
of 40 steps taking turns (which goes first alternates), every node moved a
little each step; the forces of the two checked equal bit for bit.

    .venv/bin/python bench/sessions/daemon_ab.py BEFORE/ntscontactd AFTER/ntscontactd [--rounds 10]

Prints each daemon's median own time (NTS-Elapsed-Ms), its quartiles and
the step's median wall time, then after / before. Both daemons should be
built the same way (a Release build of each commit)."""
import argparse
import pathlib
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from common import start_daemon  # noqa: E402
from python_steps import fem_scene  # noqa: E402

import ntscontact  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--steps", type=int, default=40)
    a = ap.parse_args()
    scene = fem_scene(66000)
    x0 = np.concatenate([scene.body(i).nodes for i in scene.body_ids])
    rng = np.random.default_rng(1)
    frames = [x0 + rng.normal(scale=1e-5, size=x0.shape) for _ in range(a.steps)]
    names = ("before", "after")
    procs, sessions, forces = {}, {}, {}
    own = {k: [] for k in names}
    wall = {k: [] for k in names}
    try:
        for k, binary in zip(names, (a.before, a.after)):
            procs[k], port = start_daemon(binary=binary)
            sessions[k] = ntscontact.Client(f"http://127.0.0.1:{port}", timeout=600).session(scene)
            sessions[k].contact(frames[0])
        for r in range(a.rounds):
            for k in (names if r % 2 == 0 else names[::-1]):
                for f in frames:
                    t0 = time.perf_counter()
                    res = sessions[k].contact(f)
                    wall[k].append(time.perf_counter() - t0)
                    own[k].append(res.summary.elapsed_ms)
                forces[k] = res.force_array()
            if not np.array_equal(forces["before"], forces["after"]):
                raise SystemExit("the two daemons disagree")
    finally:
        for p in procs.values():
            p.terminate()
    for k in names:
        q1, q3 = np.percentile(own[k], [25, 75])
        print(f"{k}: daemon's own time median {statistics.median(own[k]):.3f} ms (quartiles {q1:.3f}, {q3:.3f}); "
              f"the step's wall time median {1e3 * statistics.median(wall[k]):.3f} ms")
    print(f"own time, after / before: {statistics.median(own['after']) / statistics.median(own['before']):.3f}")


if __name__ == "__main__":
    main()
