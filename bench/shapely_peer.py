#!/usr/bin/env python3
"""The peer: linear NTS gaps (alpha = 0) of the same packing with Shapely (GEOS).

For every slave node and every *other* body whose boundary lies within the
search radius r: STRtree query (dwithin r) on the bodies' boundary rings, the
distance to the ring, negative when the polygon contains the node. That is our
alpha = 0 gap: the smallest |g| over the segment and vertex candidates of a
master body is the distance from the node to that body's boundary (the closest
point of a closed polygon is either the foot of a perpendicular inside a
segment, a segment candidate, or a node whose two segments both project to it,
a vertex candidate), and the sign of the segment normal or of the vertex
pseudo-normal is the sign of containment.

Like for like:
- the query runs on the *rings*, not the polygons: `dwithin` on a polygon is
  true for every point inside it, however deep, but our rule is |g| <= r, a
  distance to the boundary;
- the search radius is inclusive on both sides (|g| <= r, distance <= r); a pair
  whose distance is within round-off of r may be kept by one side only, and is
  counted apart (`edge_pairs`);
- our scene is open (not periodic): GEOS has no periodic distance.

Input: bench/results/peer_scene_N.txt and peer_gaps_N.csv written by
`nts_bench --sections peer`. Output: one row per size in peer.csv.
"""
import csv
import sys
import time

import numpy as np
import shapely


def read_scene(path):
    with open(path) as f:
        head = f.readline().split()
        nb, r = int(head[0]), float(head[1])
        ours_gaps_ns, ours_default_ns, total = float(head[2]), float(head[3]), int(head[4])
        ours_cpu_ns = float(head[5])
        bodies = []
        for _ in range(nb):
            m = int(f.readline())
            pts = np.array([[float(v) for v in f.readline().split()] for _ in range(m)])
            bodies.append(pts)
    return bodies, r, ours_gaps_ns, ours_default_ns, total, ours_cpu_ns


def shapely_gaps(bodies, r):
    """(slave_body, slave_node, master_body) -> gap, and the wall and CPU seconds it took."""
    t0, c0 = time.perf_counter(), time.process_time()
    rings = shapely.linearrings(np.concatenate(bodies), indices=np.repeat(np.arange(len(bodies)),
                                                                         [len(b) for b in bodies]))
    polys = shapely.polygons(rings)
    xy = np.concatenate(bodies)
    owner = np.repeat(np.arange(len(bodies)), [len(b) for b in bodies])
    local = np.concatenate([np.arange(len(b)) for b in bodies])
    points = shapely.points(xy)
    tree = shapely.STRtree(rings)
    pi, mj = tree.query(points, predicate="dwithin", distance=r)
    keep = owner[pi] != mj
    pi, mj = pi[keep], mj[keep]
    dist = shapely.distance(points[pi], rings[mj])
    inside = shapely.contains_xy(polys[mj], xy[pi, 0], xy[pi, 1])
    gap = np.where(inside, -dist, dist)
    t1, c1 = time.perf_counter(), time.process_time()
    return owner[pi], local[pi], mj, gap, t1 - t0, c1 - c0


def compare(scene_path, gaps_path, repeats=3):
    bodies, r, ours_gaps_ns, ours_default_ns, total, ours_cpu_ns = read_scene(scene_path)
    times, cpus = [], []
    for _ in range(repeats):
        sb, sn, mb, gap, dt, dc = shapely_gaps(bodies, r)
        times.append(dt)
        cpus.append(dc)
    theirs = {(int(a), int(b), int(c)): float(g) for a, b, c, g in zip(sb, sn, mb, gap)}
    ours = {}
    kinds = {}
    with open(gaps_path) as f:
        for row in csv.DictReader(f):
            k = (int(row["slave_body"]), int(row["slave_node"]), int(row["master_body"]))
            ours[k] = float(row["gap"])
            kinds[k] = row["kind"]
    common = sorted(set(ours) & set(theirs))
    only_ours = [k for k in ours if k not in theirs]
    only_theirs = [k for k in theirs if k not in ours]
    diffs = np.array([abs(ours[k] - theirs[k]) for k in common]) if common else np.zeros(1)
    sign_flips = sum(1 for k in common if (ours[k] < 0) != (theirs[k] < 0))
    # A pair kept by one side only must have |g| within round-off of r.
    edge = [k for k in only_ours if abs(abs(ours[k]) - r) > 1e-12 * max(1.0, r)]
    edge += [k for k in only_theirs if abs(abs(theirs[k]) - r) > 1e-12 * max(1.0, r)]
    shapely_ns = 1e9 * float(np.median(times)) / total
    shapely_cpu_ns = 1e9 * float(np.median(cpus)) / total
    return {
        "particles": len(bodies),
        "surface_nodes": total,
        "search_radius": r,
        "pairs_ours": len(ours),
        "pairs_shapely": len(theirs),
        "pairs_common": len(common),
        "only_ours": len(only_ours),
        "only_shapely": len(only_theirs),
        "unexplained_mismatch": len(edge),
        "sign_flips": sign_flips,
        "gap_diff_max": float(diffs.max()),
        "gap_diff_median": float(np.median(diffs)),
        "vertex_pairs": sum(1 for k in common if kinds[k] == "vertex"),
        "ours_ns_per_node_gaps": ours_gaps_ns,
        "ours_ns_per_node_default": ours_default_ns,
        "shapely_ns_per_node": shapely_ns,
        "speed_ratio": shapely_ns / ours_gaps_ns,
        "ours_cpu_ns_per_node_gaps": ours_cpu_ns,
        "shapely_cpu_ns_per_node": shapely_cpu_ns,
        "speed_ratio_cpu": shapely_cpu_ns / ours_cpu_ns,
        "shapely_version": shapely.__version__,
        "geos_version": shapely.geos_version_string,
    }


def run_peer(argv, compare_one, out_name):
    """compare_one(scene, gaps) for each size nts_bench's peer section wrote
    into the results directory (argv[1], else bench/results), smallest first;
    the rows into out_name there. Shared by the peers of the same gaps."""
    import glob
    import os
    if len(argv) > 1 and argv[1] in ("-h", "--help"):  # (the peer's own doc, its first lines)
        print((sys.modules["__main__"].__doc__ or "").strip() + "\n\nusage: %s [RESULTS_DIR]" % argv[0])
        return
    results = argv[1] if len(argv) > 1 else "bench/results"
    rows = []
    for scene in sorted(glob.glob(os.path.join(results, "peer_scene_*.txt")),
                        key=lambda p: int(p.rsplit("_", 1)[1].split(".")[0])):
        n = scene.rsplit("_", 1)[1].split(".")[0]
        rows.append(compare_one(scene, os.path.join(results, "peer_gaps_%s.csv" % n)))
        print(rows[-1], file=sys.stderr)
    with open(os.path.join(results, out_name), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)


def main(argv):
    run_peer(argv, compare, "peer.csv")


if __name__ == "__main__":
    main(sys.argv)
