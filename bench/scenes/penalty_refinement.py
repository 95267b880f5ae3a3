#!/usr/bin/env python3
"""Penalty per node against penalty per length under mesh refinement (issue 12).

A rigid disk of radius 1 meshed with n nodes rests on a flat floor (a "master"
body with its own alpha = 0) under a vertical load F. For each n and each
penalty_scaling, the penetration delta that balances the load (the vertical
contact force on the disk equal to F) is found by bisection on delta, each
trial one evaluation by the CLI; then the penetration and the contact pressure
under the disk's centre (the bottom node's force over its tributary length)
are reported. With "length" the penalty is a pressure stiffness: both converge
as n grows. With "node" the stiffness per unit length grows like n: the
penetration shrinks like 1/n and never converges.

    bench/scenes/penalty_refinement.py [--out docs/benchmarks.md]
"""
import argparse
import json
import math
import os
import pathlib
import subprocess
import sys

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench" / "sessions"))
from common import replace_section  # noqa: E402
CLI = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build"))) / "bin" / "ntscontact"
SECTION = "## Penalty scaling under refinement"
EPS, LOAD = 100.0, 1.0


def scene(n, delta, scaling):
    th = -math.pi / 2 + 2 * math.pi * np.arange(n) / n  # node 0 at the bottom
    disk = np.c_[np.cos(th), 1.0 - delta + np.sin(th)]
    floor = [[-3.0, -1.0], [3.0, -1.0], [3.0, 0.0], [-3.0, 0.0]]
    return {"version": 1, "options": {"penalty": EPS, "alpha": 0.2, "search_radius": 0.5,
                                       "penalty_scaling": scaling, "outputs": ["forces"]},
            "bodies": [{"id": "floor", "nodes": floor, "role": "master", "alpha": 0.0},
                       {"id": "disk", "nodes": disk.tolist()}]}


def forces(n, delta, scaling):
    r = subprocess.run([str(CLI), "-"], input=json.dumps(scene(n, delta, scaling)).encode(), capture_output=True,
                       timeout=60, check=True)
    out = json.loads(r.stdout)
    return np.array(out["bodies"][1]["forces"])


def balance(n, scaling):
    lo, hi = 0.0, 0.2
    for _ in range(60):  # bisection on the penetration: 60 halvings of 0.2
        mid = 0.5 * (lo + hi)
        if forces(n, mid, scaling)[:, 1].sum() < LOAD:
            lo = mid
        else:
            hi = mid
    delta = 0.5 * (lo + hi)
    f = forces(n, delta, scaling)
    h = 2.0 * math.sin(math.pi / n)  # segment length; the bottom node's tributary length
    return delta, f[0, 1] / h


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="64,128,256,512,1024,2048")
    ap.add_argument("--out", default=str(REPO / "docs" / "benchmarks.md"))
    a = ap.parse_args()
    rows = []
    for n in map(int, a.sizes.split(",")):
        dn, pn = balance(n, "node")
        dl, pl = balance(n, "length")
        rows.append((n, dn, pn, dl, pl))
        print(n, dn, pn, dl, pl, flush=True)
    lines = [SECTION, "",
             "A rigid disk of radius 1 with n nodes rests on a flat floor (a `master` body, its own `alpha` 0)",
             f"under a load F = {LOAD:g}, penalty {EPS:g}, the disk's alpha 0.2. For each mesh the penetration",
             "that balances the load is found by bisection (each trial one `ntscontact` run), then the pressure",
             "under the centre is the bottom node's force over its tributary length",
             "(`bench/scenes/penalty_refinement.py`).", "",
             "| nodes | node: penetration | node: pressure | length: penetration | length: pressure |",
             "|---:|---:|---:|---:|---:|"]
    for n, dn, pn, dl, pl in rows:
        lines.append(f"| {n} | {dn:.4g} | {pn:.4g} | {dl:.4g} | {pl:.4g} |")
    lines += ["", "With `penalty_scaling: \"node\"` the contact stiffness per unit length grows with the number of",
              "nodes: the penetration falls like 1/n and the pressure keeps changing with the mesh. With",
              "`\"length\"` the penalty is a pressure stiffness (per unit length of the slave surface): the",
              "penetration and the pressure converge as the mesh is refined.", "", ""]
    replace_section(a.out, SECTION, "\n".join(lines))


if __name__ == "__main__":
    main()
