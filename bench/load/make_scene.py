#!/usr/bin/env python3
"""Write a scene of pressed disks (schemas/scene.schema.json) to stdout.

    make_scene.py --side 2 --nodes 32 > small.json    # 4 disks, 128 nodes
    make_scene.py --side 30 --nodes 64 > large.json   # 900 disks, 57,600 nodes

The same scene as codec/bench/codec_bench.c builds (square packing, pitch 1.96,
radius 1 with a 0.2% jitter from the same LCG, alpha 0.2, penalty 100, search
radius 0.1), so that bench's stage timings (scan, parse, decode, scene, evaluate,
encode) split the server's latency for exactly this request. Standard library only.
"""
import argparse
import json
import math
import sys


def scene(side, m):
    r, pitch, seed = 1.0, 1.96, 12345
    bodies = []
    for i in range(side):
        for j in range(side):
            cx, cy = pitch * j, pitch * i
            nodes = []
            for k in range(m):
                a = 2.0 * math.pi * k / m
                seed = (seed * 1103515245 + 12345) & 0xFFFFFFFF
                jit = 1.0 + 0.002 * (((seed >> 16) & 0x7FFF) / 32767.0 - 0.5)
                nodes.append([cx + r * jit * math.cos(a), cy + r * jit * math.sin(a)])
            bodies.append({"id": len(bodies), "nodes": nodes})
    return {"version": 1, "options": {"alpha": 0.2, "penalty": 100.0, "search_radius": 0.1}, "bodies": bodies}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--side", type=int, default=2, help="disks per side of the square packing")
    ap.add_argument("--nodes", type=int, default=32, help="nodes per disk")
    a = ap.parse_args()
    json.dump(scene(a.side, a.nodes), sys.stdout, separators=(",", ":"))
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
