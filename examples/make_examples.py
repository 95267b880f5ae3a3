#!/usr/bin/env python3
"""Generate the bundled example scenes (deterministic: fixed seeds, stdlib only).

    python3 examples/make_examples.py            # writes examples/*.json
    python3 examples/make_examples.py DIR        # writes them into DIR instead

two_disks.json         two polygonal disks pressed together (a few active contacts)
jittered_packing.json  a 6x6 packing of disks with jittered radii, centres and nodes
periodic_packing.json  a 5x5 packing in a periodic box: disks overlap across the wrap
triangle_meshes.json   bodies given as linear triangle meshes: an annulus (a hole,
                       so two boundary loops) resting on a block, and a meshed disk
"""
import json
import math
import os
import random
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def r17(x):
    """Round to 12 significant digits: short files, and still exact doubles."""
    return float(f"{x:.12g}")


def disk(cx, cy, r, n, rng=None, node_jitter=0.0, phase=0.0):
    pts = []
    for k in range(n):
        a = phase + 2.0 * math.pi * k / n
        rr = r * (1.0 + (rng.uniform(-node_jitter, node_jitter) if rng else 0.0))
        pts.append([r17(cx + rr * math.cos(a)), r17(cy + rr * math.sin(a))])
    return pts


def two_disks():
    return {
        "version": 1,
        "options": {"alpha": 0.2, "penalty": 1000.0, "search_radius": 0.1,
                    "outputs": ["forces", "energy", "virial", "contacts"]},
        "bodies": [
            {"id": "left", "nodes": disk(0.0, 0.0, 1.0, 48)},
            {"id": "right", "nodes": disk(1.97, 0.01, 1.0, 48, phase=math.pi / 48)},
        ],
    }


def jittered_packing(seed=7):
    rng = random.Random(seed)
    bodies, pitch, side = [], 1.96, 6
    for i in range(side):
        for j in range(side):
            cx = j * pitch + rng.uniform(-0.02, 0.02)
            cy = i * pitch + rng.uniform(-0.02, 0.02)
            r = rng.uniform(0.98, 1.02)
            bodies.append({"id": i * side + j,
                           "nodes": disk(cx, cy, r, 40, rng, node_jitter=0.002, phase=rng.uniform(0, 2 * math.pi))})
    return {"version": 1,
            "options": {"alpha": 0.25, "penalty": 500.0, "search_radius": 0.1,
                        "outputs": ["forces", "contacts", "gaps"]},
            "bodies": bodies}


def periodic_packing(seed=11):
    rng = random.Random(seed)
    side, pitch = 5, 1.95
    box = side * pitch
    bodies = []
    for i in range(side):
        for j in range(side):
            # Centres near the cell centres; the first row and column sit on the
            # box edge, so their disks reach across the periodic boundary.
            cx = j * pitch + rng.uniform(-0.02, 0.02)
            cy = i * pitch + rng.uniform(-0.02, 0.02)
            cx %= box
            cy %= box
            bodies.append({"id": f"p{i}-{j}",
                           "nodes": disk(cx, cy, 1.0, 36, rng, node_jitter=0.001, phase=rng.uniform(0, 2 * math.pi))})
    return {"version": 1,
            "options": {"alpha": 0.2, "penalty": 200.0, "search_radius": 0.1,
                        "periodic": {"lx": box, "ly": box},
                        "outputs": ["forces", "energy", "virial", "contacts"]},
            "bodies": bodies}


def annulus_mesh(cx, cy, r_in, r_out, rings, m):
    """Nodes on rings+1 circles, each ring of quads split into two triangles (CCW)."""
    nodes, tris = [], []
    for i in range(rings + 1):
        r = r_in + (r_out - r_in) * i / rings
        for k in range(m):
            a = 2.0 * math.pi * k / m
            nodes.append([r17(cx + r * math.cos(a)), r17(cy + r * math.sin(a))])
    for i in range(rings):
        for k in range(m):
            a, b = i * m + k, i * m + (k + 1) % m
            c, d = a + m, b + m
            tris.append([a, b, d])
            tris.append([a, d, c])
    return nodes, tris


def disk_mesh(cx, cy, r, rings, m):
    """A centre node, then rings; the first ring is a fan around the centre."""
    nodes = [[r17(cx), r17(cy)]]
    tris = []
    for i in range(1, rings + 1):
        rr = r * i / rings
        for k in range(m):
            a = 2.0 * math.pi * (k + 0.5 * (i % 2)) / m
            nodes.append([r17(cx + rr * math.cos(a)), r17(cy + rr * math.sin(a))])
    for k in range(m):
        tris.append([0, 1 + k, 1 + (k + 1) % m])
    for i in range(1, rings):
        for k in range(m):
            a, b = 1 + (i - 1) * m + k, 1 + (i - 1) * m + (k + 1) % m
            c, d = a + m, b + m
            tris.append([a, b, d] if i % 2 else [a, b, c])
            tris.append([a, d, c] if i % 2 else [b, d, c])
    return nodes, tris


def block_mesh(x0, y0, w, h, nx, ny):
    nodes, tris = [], []
    for j in range(ny + 1):
        for i in range(nx + 1):
            nodes.append([r17(x0 + w * i / nx), r17(y0 + h * j / ny)])
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 1, a + nx + 2
            tris.append([a, b, d])
            tris.append([a, d, c])
    return nodes, tris


def triangle_meshes():
    ring_nodes, ring_tris = annulus_mesh(0.0, 1.0 - 0.015, 0.5, 1.0, 3, 40)
    block_nodes, block_tris = block_mesh(-2.0, -0.6, 4.0, 0.6, 20, 3)
    disk_nodes, disk_tris = disk_mesh(1.97, 1.0, 1.0, 4, 32)
    return {"version": 1,
            "options": {"alpha": 0.2, "penalty": 1000.0, "search_radius": 0.1,
                        "outputs": ["forces", "energy", "virial", "contacts"]},
            "bodies": [
                {"id": "ring", "nodes": ring_nodes, "triangles": ring_tris},
                {"id": 2, "nodes": block_nodes, "triangles": block_tris},
                {"id": "disk", "nodes": disk_nodes, "triangles": disk_tris},
            ]}


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else HERE
    scenes = {
        "two_disks.json": two_disks(),
        "jittered_packing.json": jittered_packing(),
        "periodic_packing.json": periodic_packing(),
        "triangle_meshes.json": triangle_meshes(),
    }
    for name, scene in scenes.items():
        path = os.path.join(out_dir, name)
        with open(path, "w") as f:
            json.dump(scene, f, separators=(",", ":"))
            f.write("\n")
        print(f"{name}: {len(scene['bodies'])} bodies, {os.path.getsize(path)} bytes")


if __name__ == "__main__":
    main()
