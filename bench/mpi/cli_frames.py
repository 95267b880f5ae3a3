#!/usr/bin/env python3
"""`ntscontact-mpi --frames`: the wall time of a run of frames, two builds side by side.

A square packing of pressed 64-node disks (bench/load/make_scene.py, SIDE x
SIDE disks) and FRAMES frames of its positions, each node moved by up to
1e-3 from the first (a solver's small steps), through `mpirun -np RANKS
ntscontact-mpi --frames` of each build given, in interleaved rounds; every
run's lines are checked equal (elapsed_ms aside) to `ntscontact --frames`'s
of the first build. Prints each build's median wall time per frame over the
rounds (the whole run, mpirun's start included, over FRAMES; the first
frame and the start are then measured apart with FRAMES = 1 and taken out).

usage: .venv/bin/python bench/mpi/cli_frames.py --builds DIR [DIR ...] [--side 40] [--frames 20] [--ranks 2] [--rounds 3]
(each DIR a CMake build with -DNTS_MPI=ON: DIR/bin/ntscontact-mpi and DIR/bin/ntscontact)
"""
import argparse
import os
import pathlib
import random
import re
import statistics
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "load"))
from make_scene import scene as make_scene  # noqa: E402

ELAPSED = re.compile(rb'"elapsed_ms":\s*[-0-9.eE+]+')
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")


def run(argv):
    t0 = time.perf_counter()
    out = subprocess.run(argv, capture_output=True, env=ENV, timeout=3600)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(argv)}: exit {out.returncode}\n{out.stderr.decode()[-2000:]}")
    return time.perf_counter() - t0, ELAPSED.sub(b"", out.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--builds", nargs="+", required=True)
    ap.add_argument("--side", type=int, default=40)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        sc = make_scene(a.side, 64)
        (tmp / "scene.json").write_text(__import__("json").dumps(sc))
        nodes = [p for b in sc["bodies"] for p in b["nodes"]]
        rng = random.Random(7)
        rows = []
        for _ in range(a.frames):
            rows.append(struct.pack(f"<{2 * len(nodes)}d",
                                    *[c + 1e-3 * (rng.random() - 0.5) for p in nodes for c in p]))
        (tmp / "frames.bin").write_bytes(b"".join(rows))
        (tmp / "one.bin").write_bytes(rows[0])
        _, want = run([str(pathlib.Path(a.builds[0]) / "bin" / "ntscontact"), "--frames", str(tmp / "frames.bin"),
                       str(tmp / "scene.json")])
        times = {b: [] for b in a.builds}
        for _ in range(a.rounds):
            for b in a.builds:
                cli = str(pathlib.Path(b) / "bin" / "ntscontact-mpi")
                t_all, got = run(["mpirun", "-np", str(a.ranks), cli, "--frames", str(tmp / "frames.bin"),
                                  str(tmp / "scene.json")])
                if got != want:
                    raise SystemExit(f"{b}: the lines differ from ntscontact's")
                t_one, _ = run(["mpirun", "-np", str(a.ranks), cli, "--frames", str(tmp / "one.bin"),
                                str(tmp / "scene.json")])
                times[b].append((t_all - t_one) / (a.frames - 1))
        print(f"{len(nodes)} nodes, {a.frames} frames, {a.ranks} ranks, {a.rounds} rounds: the lines equal ntscontact's")
        for b in a.builds:
            print(f"{b}: {1e3 * statistics.median(times[b]):.1f} ms a frame after the first "
                  f"(rounds {', '.join(f'{1e3 * t:.1f}' for t in times[b])})")


if __name__ == "__main__":
    main()
