#!/usr/bin/env python3
"""The second peer: linear NTS gaps (alpha = 0) of the same packing with a
KD-tree (scipy's cKDTree) and numpy, vectorised.

The same question as bench/shapely_peer.py (read its notes on like for like):
for every slave node and every *other* body whose boundary lies within the
search radius r, the distance to that body's boundary ring, negative when the
node is inside the polygon. Here: a cKDTree over the segments' middles;
`sparse_distance_matrix` (a KD-tree of the nodes against one of the middles) within r plus half the longest segment finds every segment
that can be within r of a node; exact point-to-segment distances in numpy;
the smallest per (node, body) kept when <= r; the sign by an even-odd count
of the body's edges crossed by a ray from the node (only for the kept pairs).

Input: bench/results/peer_scene_N.txt and peer_gaps_N.csv written by
`nts_bench --sections peer`. Output: one row per size in peer_kdtree.csv.
"""
import csv
import os
import sys
import time

import numpy as np
import scipy
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from shapely_peer import read_scene, run_peer  # noqa: E402


def kdtree_gaps(bodies, r):
    """(slave_body, slave_node, master_body, gap), and the wall and CPU seconds it took."""
    t0, c0 = time.perf_counter(), time.process_time()
    counts = np.array([len(b) for b in bodies])
    xy = np.concatenate(bodies)
    owner = np.repeat(np.arange(len(bodies)), counts)
    local = np.concatenate([np.arange(n) for n in counts])
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    nxt = np.arange(len(xy)) + 1
    last = start + counts - 1
    nxt[last] = start
    a, b = xy, xy[nxt]                      # segment k from node k to the next of its loop
    mid = 0.5 * (a + b)
    t = b - a
    l2 = np.einsum("ij,ij->i", t, t)
    reach = r + 0.5 * np.sqrt(l2.max()) * (1 + 1e-12)
    near = cKDTree(xy).sparse_distance_matrix(cKDTree(mid), reach, output_type="ndarray")
    node, seg = near["i"].astype(np.int64), near["j"].astype(np.int64)
    keep = owner[node] != owner[seg]
    node, seg = node[keep], seg[keep]
    d = xy[node] - a[seg]
    s = np.clip(np.einsum("ij,ij->i", d, t[seg]) / l2[seg], 0.0, 1.0)
    foot = a[seg] + s[:, None] * t[seg]
    dist = np.hypot(*(xy[node] - foot).T)
    # the smallest per (node, body)
    pair = node * len(bodies) + owner[seg]
    order = np.lexsort((dist, pair))
    pair_s, dist_s = pair[order], dist[order]
    first = np.concatenate([[True], pair_s[1:] != pair_s[:-1]])
    pair_u, dist_u = pair_s[first], dist_s[first]
    within = dist_u <= r
    pair_u, dist_u = pair_u[within], dist_u[within]
    pn, pb = pair_u // len(bodies), pair_u % len(bodies)
    # inside: an even-odd count of the body's edges that a ray to +x crosses,
    # every (pair, edge of its body) at once
    reps = counts[pb]
    which = np.repeat(np.arange(len(pn)), reps)
    edge = np.repeat(start[pb], reps) + (np.arange(int(reps.sum())) - np.repeat(np.cumsum(reps) - reps, reps))
    px, py = xy[pn[which], 0], xy[pn[which], 1]
    ax, ay, bx, by = a[edge, 0], a[edge, 1], b[edge, 0], b[edge, 1]
    crosses = (ay > py) != (by > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = ax + (py - ay) * (bx - ax) / (by - ay)
    hits = crosses & (xs > px)
    inside = np.bincount(which, weights=hits, minlength=len(pn)).astype(np.int64) % 2 == 1
    gap = np.where(inside, -dist_u, dist_u)
    t1, c1 = time.perf_counter(), time.process_time()
    return owner[pn], local[pn], pb, gap, t1 - t0, c1 - c0


def compare(scene_path, gaps_path, repeats=3):
    bodies, r, ours_gaps_ns, _, total, ours_cpu_ns = read_scene(scene_path)
    times, cpus = [], []
    for _ in range(repeats):
        sb, sn, mb, gap, dt, dc = kdtree_gaps(bodies, r)
        times.append(dt)
        cpus.append(dc)
    theirs = {(int(x), int(y), int(z)): float(g) for x, y, z, g in zip(sb, sn, mb, gap)}
    ours = {}
    with open(gaps_path) as f:
        for row in csv.DictReader(f):
            ours[(int(row["slave_body"]), int(row["slave_node"]), int(row["master_body"]))] = float(row["gap"])
    common = sorted(set(ours) & set(theirs))
    only_ours = [k for k in ours if k not in theirs]
    only_theirs = [k for k in theirs if k not in ours]
    diffs = np.array([abs(ours[k] - theirs[k]) for k in common]) if common else np.zeros(1)
    edge = [k for k in only_ours if abs(abs(ours[k]) - r) > 1e-12 * max(1.0, r)]
    edge += [k for k in only_theirs if abs(abs(theirs[k]) - r) > 1e-12 * max(1.0, r)]
    ns = 1e9 * float(np.median(times)) / total
    cpu_ns = 1e9 * float(np.median(cpus)) / total
    return {
        "particles": len(bodies), "surface_nodes": total, "pairs_ours": len(ours), "pairs_kdtree": len(theirs),
        "pairs_common": len(common), "only_ours": len(only_ours), "only_kdtree": len(only_theirs),
        "unexplained_mismatch": len(edge), "sign_flips": sum(1 for k in common if (ours[k] < 0) != (theirs[k] < 0)),
        "gap_diff_max": float(diffs.max()), "gap_diff_median": float(np.median(diffs)),
        "ours_cpu_ns_per_node_gaps": ours_cpu_ns, "kdtree_cpu_ns_per_node": cpu_ns,
        "speed_ratio_cpu": cpu_ns / ours_cpu_ns, "ours_ns_per_node_gaps": ours_gaps_ns, "kdtree_ns_per_node": ns,
        "speed_ratio": ns / ours_gaps_ns, "scipy_version": scipy.__version__, "numpy_version": np.__version__,
    }


def main(argv):
    run_peer(argv, compare, "peer_kdtree.csv")


if __name__ == "__main__":
    main(sys.argv)
