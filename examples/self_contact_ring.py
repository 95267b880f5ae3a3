#!/usr/bin/env python3
"""A ring squeezed flat between two plates until its inside meets itself.

The ring is one body with a hole, meshed as a ladder of triangles between
two circles, its mechanics a spring truss on the triangles' edges (along
both circles, rungs across the wall, one diagonal per cell), each at rest in
the circle it starts as. Two plates (obstacles, ``role="master"``) close in on it in ``--stages``
steps, the ring squashed with them (its heights scaled); after each step FIRE
relaxes the ring under its springs and the
contact forces, which the in-process engine (``ntscontact.Engine``, one
session for the whole run) computes at every iteration. The ring flattens,
bulges sideways, and once the plates are closer than twice its wall its
inner wall meets itself: with ``self_contact`` on (docs/model.md §16) the two
sides press on each other and stay apart; with ``--no-self`` they pass
through each other unseen.

FIRE (Bitzek et al., PRL 97, 170201, 2006), as in examples/fire_packing.py.

Usage::

    python examples/self_contact_ring.py                 # 64 cells around, 12 stages
    python examples/self_contact_ring.py --png ring.png  # and a picture (needs matplotlib)
    python examples/self_contact_ring.py --tiny --json out.json   # seconds; what the tests run
    python examples/self_contact_ring.py --tiny --no-self         # the inside passes through itself
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

try:
    import ntscontact
except ImportError:  # a checkout without `pip install -e clients/python`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "clients" / "python" / "src"))
    import ntscontact

# FIRE's standard parameters (Bitzek et al. 2006).
FIRE_NMIN, FIRE_FINC, FIRE_FDEC, FIRE_ALPHA0, FIRE_FALPHA = 5, 1.1, 0.5, 0.1, 0.99


def ring(n: int, r_out: float, r_in: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes (outer circle 0..n-1, inner circle n..2n-1, counter-clockwise),
    the triangles of the ladder between them, and the truss's springs as
    index pairs (the triangles' edges)."""
    t = 2.0 * np.pi * np.arange(n) / n
    outer = np.stack([r_out * np.cos(t), r_out * np.sin(t)], 1)
    inner = np.stack([r_in * np.cos(t), r_in * np.sin(t)], 1)
    nodes = np.concatenate([outer, inner])
    i = np.arange(n)
    springs = np.concatenate([
        np.stack([i, (i + 1) % n], 1),          # along the outer loop
        np.stack([n + i, n + (i + 1) % n], 1),  # along the inner loop
        np.stack([i, n + i], 1),                # rungs across the wall
        np.stack([i, n + (i + 1) % n], 1),      # one diagonal per cell
    ])
    # the ladder's cells, each cut along its diagonal: the ring as a triangle
    # mesh, whose boundary loops keep the orientation of its connectivity
    # however the hole deforms (docs/model.md §2: a loop body's hole is
    # oriented by its area, which turns over once its sides have crossed)
    j = (i + 1) % n
    triangles = np.concatenate([np.stack([i, j, n + j], 1), np.stack([i, n + j, n + i], 1)])
    return nodes, triangles, springs


def plate(y: float, top: bool, width: float = 4.0, h: float = 0.3) -> np.ndarray:
    """A rectangle whose contact face lies at y (facing the ring)."""
    y0, y1 = (y, y + h) if top else (y - h, y)
    return np.array([[-width / 2, y0], [width / 2, y0], [width / 2, y1], [-width / 2, y1]])


def spring_forces(x: np.ndarray, springs: np.ndarray, rest: np.ndarray, k: np.ndarray) -> Tuple[float, np.ndarray]:
    """Energy sum k/2 (l - l0)^2 and its forces."""
    d = x[springs[:, 1]] - x[springs[:, 0]]
    length = np.hypot(d[:, 0], d[:, 1])
    stretch = length - rest
    f = (k * stretch / length)[:, None] * d  # on node 0 of each spring, towards node 1 when stretched
    out = np.zeros_like(x)
    np.add.at(out, springs[:, 0], f)
    np.add.at(out, springs[:, 1], -f)
    return float(0.5 * np.sum(k * stretch**2)), out


def fire(force, x: np.ndarray, tol: float, max_iter: int, dt0: float, dt_max: float) -> Tuple[np.ndarray, int, float]:
    """Relax x to max |F| < tol; returns the positions, the iterations and the residual."""
    v = np.zeros_like(x)
    dt, a, since = dt0, FIRE_ALPHA0, 0
    f = force(x)
    res = float(np.max(np.hypot(f[:, 0], f[:, 1])))
    it = 0
    while it < max_iter and res > tol:
        it += 1
        p = float(np.sum(f * v))
        if p > 0.0:
            vn, fn = np.linalg.norm(v), np.linalg.norm(f)
            v = (1.0 - a) * v + a * vn * f / max(fn, 1e-300)
            since += 1
            if since > FIRE_NMIN:
                dt, a = min(dt * FIRE_FINC, dt_max), a * FIRE_FALPHA
        else:
            v[:] = 0.0
            dt, a, since = dt * FIRE_FDEC, FIRE_ALPHA0, 0
        v = v + dt * f
        x = x + dt * v
        f = force(x)
        res = float(np.max(np.hypot(f[:, 0], f[:, 1])))
    return x, it, res


def inner_overlap(x: np.ndarray, n: int) -> float:
    """How far the inner wall's top half has gone below its bottom half over
    the middle of the ring (|x| < 0.3): 0 when apart, a penalty's small
    penetration when pressed together, about a wall's thickness when one side
    has passed through the other."""
    inner = x[n:]
    mid = np.abs(inner[:, 0]) < 0.3
    top = inner[mid & (np.arange(n) < n // 2)]
    bottom = inner[mid & (np.arange(n) >= n // 2)]
    return float(max(0.0, bottom[:, 1].max() - top[:, 1].min()))


def run(n: int, stages: int, self_contact: bool, tol: float, max_iter: int,
        penalty: float) -> Tuple[Dict[str, object], np.ndarray, "ntscontact.Scene", "ntscontact.Result"]:
    r_out, r_in = 1.0, 0.85
    nodes, triangles, springs = ring(n, r_out, r_in)
    rest = np.hypot(*(nodes[springs[:, 1]] - nodes[springs[:, 0]]).T)
    # the wall's rungs and diagonals ten times stiffer than the loops: the
    # wall keeps its thickness, and the ring bends rather than thins
    k = np.where(np.arange(len(springs)) < 2 * n, 50.0, 500.0)
    scene = ntscontact.Scene(penalty=penalty, alpha=0.2, outputs=["forces", "energy", "contacts"])
    scene.add_body(nodes, triangles=triangles, id="ring", self_contact=self_contact)
    scene.add_body(plate(r_out, True), id="top", role="master")
    scene.add_body(plate(-r_out, False), id="bottom", role="master")
    m = len(nodes)
    # the plates close from the ring's diameter to 90% of two walls: the inside must close
    gap_end = 2.0 * (r_out - r_in) * 0.9
    heights = np.linspace(r_out, gap_end / 2.0, stages + 1)[1:]
    stats: List[Dict[str, float]] = []
    x = nodes.copy()
    with ntscontact.Engine() as engine, engine.session(scene) as s:
        last: Dict[str, ntscontact.Result] = {}

        def total_force(xr: np.ndarray, plates: np.ndarray) -> np.ndarray:
            res = s.contact(np.concatenate([xr, plates]), outputs=["forces"])
            last["r"] = res
            return spring_forces(xr, springs, rest, k)[1] + res.force_array()[:m]

        h_prev = r_out
        for h in heights:
            plates = np.concatenate([plate(h, True), plate(-h, False)])
            # The ring squashed with the plates first (y scaled by the same
            # ratio, which keeps every wall on its side), then relaxed: no
            # stage starts with the plates deep in the ring.
            x[:, 1] *= h / h_prev
            h_prev = h
            x, it, res = fire(lambda xr: total_force(xr, plates), x, tol, max_iter, dt0=0.003, dt_max=0.01)
            final = s.contact(np.concatenate([x, plates]), outputs=["forces", "energy", "contacts"])
            self_contacts = sum(1 for c in final.contacts if c.slave_body == c.master_body == "ring")
            stats.append({"half_gap": float(h), "iterations": it, "residual": res,
                          "contacts": len(final.contacts), "self_contacts": self_contacts,
                          "max_penetration": float(final.summary.max_penetration)})
        final_scene = scene
        final_scene.set_nodes("ring", x)
        final_scene.set_nodes("top", plate(heights[-1], True))
        final_scene.set_nodes("bottom", plate(-heights[-1], False))
    summary = {"self_contact": self_contact, "cells": n, "wall": r_out - r_in, "stages": stats,
               "inner_overlap": inner_overlap(x, n),
               "self_contacts": stats[-1]["self_contacts"], "max_penetration": stats[-1]["max_penetration"]}
    return summary, x, final_scene, final


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tiny", action="store_true", help="32 cells around, 10 stages: seconds, for the tests")
    p.add_argument("--cells", type=int, default=64, help="cells around the ring (nodes per loop)")
    p.add_argument("--stages", type=int, default=20)
    p.add_argument("--penalty", type=float, default=5000.0)
    p.add_argument("--tol", type=float, default=1e-3, help="FIRE's residual, max |F|")
    p.add_argument("--max-iter", type=int, default=20000)
    p.add_argument("--no-self", action="store_true", help="self-contact off: the inside passes through itself")
    p.add_argument("--json", help="write the run's figures")
    p.add_argument("--png", help="draw the squeezed ring and its contact forces (needs matplotlib)")
    a = p.parse_args(argv)
    cells, stages = (32, 10) if a.tiny else (a.cells, a.stages)
    summary, x, scene, result = run(cells, stages, not a.no_self, a.tol, a.max_iter, a.penalty)
    for st in summary["stages"]:
        print(f"plates at +-{st['half_gap']:.3f}: {st['iterations']:5d} FIRE iterations, residual "
              f"{st['residual']:.1e}, contacts {st['contacts']:3d} (self {st['self_contacts']:3d}), "
              f"max penetration {st['max_penetration']:.2e}")
    print(f"self-contact {'on' if summary['self_contact'] else 'off'}: the inside's two sides overlap by "
          f"{summary['inner_overlap']:.2e} (the plates squeeze the two walls by "
          f"{2.0 * summary['wall'] - 2.0 * summary['stages'][-1]['half_gap']:.2e})")
    if a.json:
        Path(a.json).write_text(json.dumps(summary, indent=2) + "\n")
    if a.png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(8, 2.6))
        ntscontact.plot(scene, result, ax=ax)
        ax.set_xlim(-1.7, 1.7)  # the ring, and the plates' middle
        ax.set_ylim(-0.4, 0.4)
        ax.set_title("A ring squeezed until its inside meets itself (self-contact on)")
        fig.savefig(a.png, dpi=120, bbox_inches="tight")
    return 0


if __name__ == "__main__":
    sys.exit(main())
