#!/usr/bin/env python3
"""A solver step in process (`ntscontact.Engine`) beside the same step over HTTP
(issue 28, item 1).

Scenes: square packings of pressed 64-node disks (bench/load/make_scene.py) of
256, 25,600 and 102,400 nodes, and the 66k-node FEM scene of python_steps.py,
with every node and with a surface exchange (exchange="surface"). Each
round moves every node (a fresh frame) and takes, interleaved:

  engine      s.contact(x).force_array() on an Engine session (the default: a
              kept candidate list), wall time in Python;
  engine/off  the same with keep_candidates=False: every step an evaluation
              from scratch;
  C           the library's own time of that evaluation from scratch (the
              step's elapsed_ms: positions checked, evaluation, forces written);
  http        the same step through Client(url).session (default options), wall.

Ratios: engine/off over C is what the Python door adds at equal work; engine
over C is a solver's step in Python against the C evaluation from scratch
(target, issue 28: at most 1.1 at 25,600 and 1e5 nodes). Forces of all three
are checked equal, bit for bit, every round. One evaluation thread everywhere.

    bench/sessions/engine_steps.py [--sizes 20,40] [--repeats 15] [--out docs/benchmarks.md]

Writes bench/results/sessions_engine.csv and the section "In process: the
engine from Python" of docs/benchmarks.md.
"""
import argparse
import json
import os
import pathlib
import statistics
import sys
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))
sys.path.insert(0, str(REPO / "bench" / "sessions"))
from common import start_daemon, write_results  # noqa: E402
from python_steps import fem_scene, packing_scene  # noqa: E402

import ntscontact  # noqa: E402

SECTION = "## In process: the engine from Python"


def measure(engine, client, name, scene, repeats, exchange="all"):
    x0 = np.concatenate([scene.body(i).nodes for i in scene.body_ids])
    rng = np.random.default_rng(len(x0))
    frames = [x0 + rng.normal(scale=1e-5, size=x0.shape) for _ in range(repeats + 1)]
    t_kept, t_off, t_c, t_http = [], [], [], []
    with engine.session(scene, exchange=exchange) as kept, \
            engine.session(scene, keep_candidates=False, exchange=exchange) as off, \
            client.session(scene, exchange=exchange) as http:
        for s in (kept, off, http):  # warm: the first step builds what the next ones reuse
            s.contact(frames[0]).force_array()
        for x in frames[1:]:
            t0 = time.perf_counter()
            f_kept = kept.contact(x).force_array()
            t1 = time.perf_counter()
            r_off = off.contact(x)
            f_off = r_off.force_array()
            t2 = time.perf_counter()
            f_http = http.contact(x).force_array()
            t3 = time.perf_counter()
            assert np.array_equal(f_kept, f_off) and np.array_equal(f_kept, f_http), "the doors disagree"
            t_kept.append(t1 - t0)
            t_off.append(t2 - t1)
            t_http.append(t3 - t2)
            t_c.append(1e-3 * r_off.summary.elapsed_ms)
    med = {k: 1e3 * statistics.median(v) for k, v in
           (("engine_ms", t_kept), ("engine_off_ms", t_off), ("c_ms", t_c), ("http_ms", t_http))}
    door = [a / c for a, c in zip(t_off, t_c)]
    step = [a / c for a, c in zip(t_kept, t_c)]
    return {"scene": name, "nodes": int(len(x0)), **med,
            "door": statistics.median(door), "door_min": min(door), "door_max": max(door),
            "engine_over_c": statistics.median(step), "engine_over_c_min": min(step),
            "engine_over_c_max": max(step), "http_over_engine": med["http_ms"] / med["engine_ms"]}


def markdown(rows, repeats, commit, build_type):
    lines = [SECTION, "",
             f"`bench/sessions/engine_steps.py --repeats {repeats}` (commit {commit}, the library and the daemon of a "
             f"{build_type} build: `NTS_BUILD_DIR={BUILD.name}`), one evaluation thread, "
             "medians of interleaved rounds that each move every node.",
             "**engine**: `s.contact(x).force_array()` on an `Engine` session (its default kept candidate list);",
             "**engine, from scratch**: the same with `keep_candidates=False`; **C**: the library's own time of",
             "that evaluation from scratch (the step's `elapsed_ms`); **http**: the same step through",
             "`Client(url).session` to a local daemon. The forces of the three are checked equal, bit for bit,",
             "every round. **door** = engine from scratch / C, what Python and ctypes add at equal work;",
             "**engine / C** = a solver's step in Python against the C evaluation from scratch (target,",
             "issue 28: at most 1.1 at 25,600 and 1e5 nodes). The last row is the FEM scene's steps with",
             "`exchange=\"surface\"` on all three sessions (the surface nodes' rows alone go in and out).", "",
             "| scene | nodes | engine | engine, from scratch | C | http | door | engine / C | http / engine |",
             "|---|---:|---:|---:|---:|---:|---|---|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['nodes']:,} | {r['engine_ms']:.2f} ms | {r['engine_off_ms']:.2f} ms "
                     f"| {r['c_ms']:.2f} ms | {r['http_ms']:.2f} ms "
                     f"| {r['door']:.3f} ({r['door_min']:.3f}-{r['door_max']:.3f}) "
                     f"| {r['engine_over_c']:.2f} ({r['engine_over_c_min']:.2f}-{r['engine_over_c_max']:.2f}) "
                     f"| {r['http_over_engine']:.2f}x |")
    lines.append("")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="2,20,40", help="disks per side of the packings (x64 nodes each)")
    ap.add_argument("--fem-nodes", type=int, default=66000)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--library", default=str(BUILD / "lib" / "libntscontact_engine.so"))
    ap.add_argument("--out", default=str(REPO / "docs" / "benchmarks.md"))
    a = ap.parse_args()
    import subprocess
    commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    proc, port = start_daemon()
    rows = []
    try:
        with ntscontact.Engine(library=a.library) as engine, \
                ntscontact.Client(f"http://127.0.0.1:{port}", timeout=600) as client:
            scenes = [(f"packing {s}x{s} disks", packing_scene(s)) for s in map(int, a.sizes.split(","))]
            scenes.append(("FEM: 4 triangle-mesh disks", fem_scene(a.fem_nodes)))
            for name, scene in scenes:
                rows.append(measure(engine, client, name, scene, a.repeats))
                print(json.dumps(rows[-1]), flush=True)
            # the same FEM steps exchanging the surface nodes' rows alone (?nodes=surface)
            rows.append(measure(engine, client, "FEM, surface exchange", fem_scene(a.fem_nodes), a.repeats,
                                exchange="surface"))
            print(json.dumps(rows[-1]), flush=True)
    finally:
        proc.terminate()
        proc.wait(timeout=60)
    cache = BUILD / "CMakeCache.txt"
    build_type = next((line.split("=", 1)[1].strip() for line in cache.read_text().splitlines()
                       if line.startswith("CMAKE_BUILD_TYPE:")), "?") if cache.exists() else "?"
    write_results(rows, "sessions_engine.csv", a.out, SECTION, markdown(rows, a.repeats, commit, build_type))


if __name__ == "__main__":
    main()
