#!/usr/bin/env python3
"""Write a scene of pressed disks on a grid (schemas/scene.schema.json).

    make_scene.py --grid 2x1 --nodes 32 > small.json     # two disks, 64 nodes
    make_scene.py --grid 30x30 --nodes 64 > large.json   # 900 disks, 57,600 nodes

Neighbouring disks of radius 1 sit 1.95 apart, so every pair overlaps a little
and every disk has contacts: the evaluation does real work. Standard library only.
"""
import argparse
import json
import math
import sys


def scene(nx, ny, nodes, pitch=1.95, radius=1.0):
    bodies = []
    for j in range(ny):
        for i in range(nx):
            cx, cy = i * pitch, j * pitch
            pts = [[round(cx + radius * math.cos(2 * math.pi * k / nodes), 12),
                    round(cy + radius * math.sin(2 * math.pi * k / nodes), 12)] for k in range(nodes)]
            bodies.append({"id": f"d{i}_{j}", "nodes": pts})
    return {"version": 1, "options": {"alpha": 0.2, "penalty": 100.0}, "bodies": bodies}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--grid", default="2x1", help="disks along x and y, e.g. 30x30")
    ap.add_argument("--nodes", type=int, default=32, help="nodes per disk")
    a = ap.parse_args()
    nx, ny = (int(v) for v in a.grid.lower().split("x"))
    json.dump(scene(nx, ny, a.nodes), sys.stdout, separators=(",", ":"))
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
