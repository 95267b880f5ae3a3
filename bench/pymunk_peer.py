#!/usr/bin/env python3
"""The third peer: pymunk (Chipmunk2D) stepping the same packing as rigid
convex polygons.

Not the same question, and said so in every row: pymunk treats each body as
a rigid convex polygon (`pymunk.Poly`, the convex hull of its nodes) and its
step finds, for each overlapping pair, at most 2 contact points, then solves
for impulses; ours evaluates every slave node of a deformable body against
every other body (its closest point on the smoothed surface, gap, force,
energy, virial), which is what an FEM or soft-particle code needs. The
packing is the one of bench/shapely_peer.py (open, the particles convex
polygons of many nodes overlapping a little), zero gravity, dt = 1e-3.

Reported per size: pymunk's ns per surface node per `space.step` (median of
the steps after the first, wall and CPU), its arbiters (overlapping pairs)
and contact points, and, from the scene file's header, our evaluation's ns
per node and our active contacts (g < 0; default outputs, alpha 0, the
explicit search radius r of that file; empty when the file is older than the
header's seventh field), and our solver's step with a kept candidate list on
the same packing and options (the header's eighth field: `nts_bench`'s
kept_step_ns, each body moved a little each step, the positions given in one
call), the comparison issue 27 §5 asks for; and that loop's mean step,
the list's builds included (the ninth field: the median is a step between
builds, and since 044d390 a build does more so that the steps between do
less).

Input: bench/results/peer_scene_N.txt (`nts_bench --sections peer`).
Output: one row per size in peer_pymunk.csv.

Paired rounds (`--rounds R [--nts-bench PATH]`): each round runs
`nts_bench --sections peer` into a directory of its own, then pymunk right
after on the packings it wrote (the median of 20 steps after the first,
as ours is of 20), so that each round's ratio compares two runs seconds
apart; printed: per size the medians over the rounds, each round's ratio
pymunk / ours kept, and their median (the figure issue 27 §5 asks for:
above 1, ours is faster). This VM's speed moves by 30% between runs, so a
single run's ratio says little.
"""
import csv
import os
import sys
import time

import numpy as np
import pymunk

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from shapely_peer import read_scene  # noqa: E402


def header_field(path, k, kind, absent):
    """Field k (0-based) of the scene file's header as `kind`, or `absent` when the header is shorter."""
    with open(path) as f:
        head = f.readline().split()
    return kind(head[k]) if len(head) > k else absent


def ours_contacts(path):
    """Our active contacts from the scene header's seventh field, or "" when absent."""
    return header_field(path, 6, int, "")


def ours_kept(path):
    """Our ns per node of a solver's step with a kept list (the header's eighth field), or None."""
    return header_field(path, 7, float, None)


def ours_kept_mean(path):
    """The mean of the same steps, the list's builds included (the ninth field), or None."""
    return header_field(path, 8, float, None)


def step_packing(bodies, steps=6, dt=1e-3):
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    rigid = []
    for pts in bodies:
        c = pts.mean(axis=0)
        b = pymunk.Body(1.0, 1.0)
        b.position = (float(c[0]), float(c[1]))
        shape = pymunk.Poly(b, [(float(x - c[0]), float(y - c[1])) for x, y in pts])
        space.add(b, shape)
        rigid.append(b)
    wall, cpu = [], []
    for k in range(steps):
        t0, c0 = time.perf_counter(), time.process_time()
        space.step(dt)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    arbiters, points = 0, 0
    counted = []

    def count(arb):
        counted.append(len(arb.contact_point_set.points))

    for b in rigid:
        b.each_arbiter(count)
    arbiters, points = len(counted) // 2, sum(counted) // 2  # each pair seen from both bodies
    return float(np.median(wall[1:])), float(np.median(cpu[1:])), arbiters, points


def scenes_in(results):
    import glob
    return sorted(glob.glob(os.path.join(results, "peer_scene_*.txt")),
                  key=lambda p: int(p.rsplit("_", 1)[1].split(".")[0]))


def paired_rounds(rounds, nts_bench):
    """Each round: our kept step (nts_bench) then pymunk's, seconds apart; a table of the ratios."""
    import subprocess
    import tempfile
    per_size = {}
    for q in range(rounds):
        with tempfile.TemporaryDirectory(prefix="nts-peer-") as tmp:
            try:
                run = subprocess.run([nts_bench, "--out", tmp, "--sections", "peer"], capture_output=True, text=True)
            except OSError as e:
                sys.exit(f"cannot run {nts_bench}: {e}")
            if run.returncode != 0 or not scenes_in(tmp):
                sys.exit(f"{nts_bench} wrote no peer scenes (exit {run.returncode}): {run.stderr.strip()}")
            for scene in scenes_in(tmp):
                bodies, _, _, _, total, _ = read_scene(scene)
                wall, _, _, _ = step_packing(bodies, steps=21)
                ours = ours_kept(scene)
                if not ours:
                    sys.exit(f"{scene}: no kept step's time in its header (an nts_bench older than the kept step)")
                mean = ours_kept_mean(scene)
                row = per_size.setdefault(len(bodies), {"nodes": total, "pymunk": [], "ours": [], "ratio": [],
                                                        "ours_mean": [], "ratio_mean": []})
                row["pymunk"].append(1e9 * wall / total)
                row["ours"].append(ours)
                row["ratio"].append(1e9 * wall / total / ours)
                if mean:
                    row["ours_mean"].append(mean)
                    row["ratio_mean"].append(1e9 * wall / total / mean)
        print(f"round {q + 1} of {rounds} done", file=sys.stderr)
    # The step's median is a step between the list's builds; the loop's mean
    # (the same steps, builds included) is what a solver pays on average.
    print("| particles | surface nodes | pymunk ns/node per step (median) | ours: kept step ns/node (median) "
          "| pymunk / ours kept (median; range) | rounds (sorted) | ours: the loop's mean ns/node, builds included "
          "| pymunk / ours, the loop's mean (median; range) |")
    print("|---:|---:|---:|---:|---|---|---:|---|")
    for particles, row in sorted(per_size.items()):
        ratios = sorted(row["ratio"])
        means = sorted(row["ratio_mean"])
        mean_cells = (f"{np.median(row['ours_mean']):.1f} | {np.median(means):.3f} ({means[0]:.3f}-{means[-1]:.3f})"
                      if means else " | ")
        print(f"| {particles} | {row['nodes']} | {np.median(row['pymunk']):.1f} | {np.median(row['ours']):.1f} "
              f"| {np.median(ratios):.3f} ({ratios[0]:.3f}-{ratios[-1]:.3f}) "
              f"| {', '.join(f'{x:.2f}' for x in ratios)} | {mean_cells} |")


def main(argv):
    import argparse
    ap = argparse.ArgumentParser(description="pymunk against our evaluation and kept step (issue 27 §5)")
    ap.add_argument("results", nargs="?", default="bench/results",
                    help="the directory of nts_bench's peer_scene_N.txt (without --rounds)")
    ap.add_argument("--rounds", type=int, help="paired rounds, each running nts_bench anew")
    ap.add_argument("--nts-bench", help="with --rounds: the nts_bench to run (default: the Release build's, "
                                        "build-bench/bin/nts_bench, else build/bin/nts_bench)")
    a = ap.parse_args(argv[1:])
    if a.rounds is not None:
        if a.rounds < 1:
            ap.error("--rounds must be at least 1")
        exe = a.nts_bench
        if exe is None:
            exe = next((c for c in ("build-bench/bin/nts_bench", "build/bin/nts_bench") if os.path.exists(c)),
                       "build-bench/bin/nts_bench")
            print(f"nts_bench: {exe}", file=sys.stderr)
        paired_rounds(a.rounds, exe)
        return
    results = a.results
    rows = []
    for scene in scenes_in(results):
        bodies, r, ours_gaps_ns, ours_default_ns, total, _ = read_scene(scene)
        wall, cpu, arbiters, points = step_packing(bodies)
        rows.append({
            "particles": len(bodies), "surface_nodes": total,
            "pymunk_ns_per_node_step": 1e9 * wall / total, "pymunk_cpu_ns_per_node_step": 1e9 * cpu / total,
            "pymunk_arbiters": arbiters, "pymunk_contact_points": points,
            "ours_active_contacts": ours_contacts(scene), "ours_ns_per_node_default": ours_default_ns,
            "pymunk_over_ours": (1e9 * wall / total) / ours_default_ns,
            "ours_ns_per_node_kept_step": ours_kept(scene) if ours_kept(scene) is not None else "",
            "pymunk_over_ours_kept": (1e9 * wall / total) / ours_kept(scene) if ours_kept(scene) else "",
            "ours_ns_per_node_kept_loop_mean": ours_kept_mean(scene) if ours_kept_mean(scene) is not None else "",
            "pymunk_over_ours_kept_loop_mean":
                (1e9 * wall / total) / ours_kept_mean(scene) if ours_kept_mean(scene) else "",
            "pymunk_version": pymunk.version, "chipmunk_version": pymunk.chipmunk_version,
            "what_pymunk_computes": "rigid convex hulls; <= 2 contact points per overlapping pair; impulses",
            "what_we_compute": "every slave node: closest point on the smoothed surface, gap, force, energy, virial",
        })
        print(rows[-1], file=sys.stderr)
    with open(os.path.join(results, "peer_pymunk.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    main(sys.argv)
