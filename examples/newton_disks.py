#!/usr/bin/env python3
"""Implicit quasi-static contact: elastic disks stacked on a floor, solved by
Newton's method with the contact tangent, against FIRE with forces only.

Two linear-elastic disks (plane strain, linear triangles, own assembly below)
rest one on the other on a rigid floor under their own weight. The floor is a
`master` body with its own alpha 0; the contact penalty is per unit length
(`penalty_scaling: "length"`). The contact scene lives in the service as a
session: every Newton iteration sends the positions and gets back the contact
forces, energy and tangent (`outputs: ["forces", "energy", "stiffness"]`).

Newton minimises the total energy Pi(u) = 1/2 u K u - f u + E_contact(X + u)
with a backtracking line search on Pi; FIRE minimises the same energy with the
same constraints from the forces alone. Both stop when the largest residual
force is below --tol. The symmetry axis (the centre and top node of each disk)
is held in x: a frictionless stack has no horizontal stiffness otherwise.

    .venv/bin/python examples/newton_disks.py [--rings 8] [--tol 1e-8] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "clients" / "python" / "src"))
import ntscontact  # noqa: E402
from ntscontact.mesh import disk_mesh  # noqa: E402


# ------------------------------------------------------------- the bodies


def elastic_stiffness(nodes: np.ndarray, tris: np.ndarray, E: float, nu: float) -> sp.csr_matrix:
    """Plane-strain linear elasticity on constant-strain triangles: sum over
    triangles of area * B^T D B (dofs 2 node + component)."""
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    D = np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])
    p = nodes[tris]                                   # (m, 3, 2)
    b = np.stack([p[:, 1, 1] - p[:, 2, 1], p[:, 2, 1] - p[:, 0, 1], p[:, 0, 1] - p[:, 1, 1]], axis=1)
    c = np.stack([p[:, 2, 0] - p[:, 1, 0], p[:, 0, 0] - p[:, 2, 0], p[:, 1, 0] - p[:, 0, 0]], axis=1)
    area2 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])
    B = np.zeros((len(tris), 3, 6))
    B[:, 0, 0::2] = b
    B[:, 1, 1::2] = c
    B[:, 2, 0::2] = c
    B[:, 2, 1::2] = b
    B /= area2[:, None, None]
    ke = 0.5 * np.abs(area2)[:, None, None] * np.einsum("mki,kl,mlj->mij", B, D, B)
    dof = np.stack([2 * tris[:, 0], 2 * tris[:, 0] + 1, 2 * tris[:, 1], 2 * tris[:, 1] + 1,
                    2 * tris[:, 2], 2 * tris[:, 2] + 1], axis=1)
    rows = np.repeat(dof, 6, axis=1).ravel()
    cols = np.tile(dof, (1, 6)).ravel()
    n = 2 * len(nodes)
    return sp.csr_matrix((ke.ravel(), (rows, cols)), shape=(n, n))


class Problem:
    """Two disks on a floor: the contact scene, the elastic stiffness, the weight,
    and the constrained degrees of freedom (global node order of the scene)."""

    def __init__(self, rings: int, E: float, nu: float, weight: float, penalty: float, alpha: float) -> None:
        d0, t0 = disk_mesh(1.0, rings, 0.0, 0.995)        # 0.005 into the floor
        d1, t1 = disk_mesh(1.0, rings, 0.0, 2.985)        # 0.005 into the lower disk
        floor = np.array([[-3.0, -1.0], [3.0, -1.0], [3.0, 0.0], [-3.0, 0.0]])
        self.scene = ntscontact.Scene(penalty=penalty, alpha=alpha, penalty_scaling="length",
                                      search_radius=0.05, outputs=["forces", "energy"])
        self.scene.add_body(d0, triangles=t0, id="lower")
        self.scene.add_body(d1, triangles=t1, id="upper")
        self.scene.add_body(floor, id="floor", alpha=0.0, role="master")
        self.X = self.scene.positions()
        n0 = len(d0)
        self.n = len(self.X)
        K = sp.block_diag([elastic_stiffness(d0, t0, E, nu), elastic_stiffness(d1, t1, E, nu),
                           sp.csr_matrix((8, 8))]).tocsr()
        self.K = K
        # Weight: each triangle's share (area / 3) on its nodes, downward.
        f = np.zeros(2 * self.n)
        for nodes, tris, off in ((d0, t0, 0), (d1, t1, n0)):
            p = nodes[tris]
            area = 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                                - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
            np.add.at(f, 2 * (tris + off).ravel() + 1, np.repeat(-weight * area / area.sum() / 3.0, 3))
        self.f = f
        if rings % 2:
            raise SystemExit("--rings must be even (a node on the symmetry axis at the top)")
        top = 1 + 3 * rings * (rings - 1) + 6 * rings // 4   # the node at angle 90 on the outer ring
        fixed = [2 * (self.n - 4 + i) + c for i in range(4) for c in (0, 1)]   # the floor
        for off in (0, n0):
            fixed += [2 * off, 2 * (off + top)]               # x of the centre and of the top node
        self.fixed = np.array(sorted(fixed))
        self.free = np.setdiff1d(np.arange(2 * self.n), self.fixed)

    def energy(self, u: np.ndarray, contact_energy: float) -> float:
        return 0.5 * float(u @ (self.K @ u)) - float(self.f @ u) + contact_energy


# ------------------------------------------------------------- the solvers


def newton(p: Problem, session: Any, tol: float, max_iter: int = 50) -> Dict[str, Any]:
    u = np.zeros(2 * p.n)
    history: List[float] = []
    calls = 0
    t0 = time.perf_counter()
    res = session.contact(p.X, outputs=["forces", "energy", "stiffness"])
    calls += 1
    for it in range(max_iter + 1):
        g = p.K @ u - p.f - res.force_array().ravel()      # dPi/du
        g[p.fixed] = 0.0
        norm = float(np.abs(g).max())
        history.append(norm)
        if norm < tol or it == max_iter:
            break
        J = (p.K + res.stiffness).tocsr()[p.free][:, p.free]
        du = np.zeros_like(u)
        du[p.free] = spla.spsolve(J.tocsc(), -g[p.free])
        pi0, slope, t = p.energy(u, res.energy), float(g @ du), 1.0
        for _ in range(30):
            # Backtracking (Armijo) on the total energy. Near the solution the
            # energy's change drowns in its round-off: a step that lowers the
            # residual is accepted too.
            trial = session.contact((p.X.ravel() + u + t * du).reshape(-1, 2),
                                    outputs=["forces", "energy", "stiffness"])
            calls += 1
            gt = p.K @ (u + t * du) - p.f - trial.force_array().ravel()
            gt[p.fixed] = 0.0
            if (p.energy(u + t * du, trial.energy) <= pi0 + 1e-4 * t * slope
                    or float(np.abs(gt).max()) < (1 - 1e-4 * t) * norm or t < 1e-8):
                break
            t *= 0.5
        u, res = u + t * du, trial
    return {"method": "newton", "iterations": len(history) - 1, "calls": calls, "residual": history[-1],
            "converged": history[-1] < tol, "seconds": time.perf_counter() - t0, "history": history, "u": u}


def fire(p: Problem, session: Any, tol: float, max_iter: int, dt0: float) -> Dict[str, Any]:
    """FIRE (Bitzek et al. 2006) on Pi with unit masses, forces only."""
    u = np.zeros(2 * p.n)
    v = np.zeros_like(u)
    calls = 0
    t0 = time.perf_counter()

    def force(u: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        r = session.contact((p.X.ravel() + u).reshape(-1, 2), outputs=["forces"])
        f = p.f + r.force_array().ravel() - p.K @ u
        f[p.fixed] = 0.0
        return f

    f = force(u)
    dt, dt_max, a, npos, it = dt0, 10 * dt0, 0.1, 0, 0
    residual = float(np.abs(f).max())
    while residual >= tol and it < max_iter:
        power = float(f @ v)
        if power > 0:
            v = (1 - a) * v + a * np.linalg.norm(v) / np.linalg.norm(f) * f
            if npos > 5:
                dt, a = min(1.1 * dt, dt_max), 0.99 * a
            npos += 1
        else:
            v[:] = 0.0
            dt, a, npos = 0.5 * dt, 0.1, 0
        v += dt * f
        u = u + dt * v
        f = force(u)
        residual = float(np.abs(f).max())
        it += 1
    return {"method": "fire", "iterations": it, "calls": calls, "residual": residual, "converged": residual < tol,
            "seconds": time.perf_counter() - t0, "u": u}


# ------------------------------------------------------------- the service


def start_daemon(build_dir: Path) -> Tuple[subprocess.Popen, str]:
    exe = build_dir / "bin" / "ntscontactd"
    if not exe.exists():
        raise SystemExit(f"{exe} not found: build it (bash scripts/build.sh) or give --url")
    proc = subprocess.Popen([str(exe), "--port", "0", "--quiet"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], 10.0)
    m = re.search(r":(\d+)\s*$", proc.stdout.readline() if ready else "")
    if not m:
        proc.kill()
        raise SystemExit("ntscontactd did not report its port")
    return proc, f"http://127.0.0.1:{m.group(1)}"


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", help="a running ntscontactd (default: start one from the build dir)")
    ap.add_argument("--build-dir", default=os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))
    ap.add_argument("--rings", type=int, default=8, help="mesh rings per disk (1 + 3 r (r + 1) nodes)")
    ap.add_argument("--E", type=float, default=1000.0)
    ap.add_argument("--nu", type=float, default=0.3)
    ap.add_argument("--weight", type=float, default=20.0, help="weight of each disk")
    ap.add_argument("--penalty", type=float, default=1e5, help="per unit length")
    ap.add_argument("--alpha", type=float, default=0.2)
    ap.add_argument("--tol", type=float, default=1e-8, help="largest residual force")
    ap.add_argument("--fire-max", type=int, default=200000)
    ap.add_argument("--no-fire", action="store_true")
    ap.add_argument("--json", help="write the runs (without the displacements) as JSON")
    args = ap.parse_args(argv)
    p = Problem(args.rings, args.E, args.nu, args.weight, args.penalty, args.alpha)
    proc, url = (None, args.url) if args.url else start_daemon(Path(args.build_dir))
    runs = []
    try:
        with ntscontact.Client(url, timeout=120.0) as client, client.session(p.scene) as s:
            runs.append(newton(p, s, args.tol))
            if not args.no_fire:
                # dt from the stiffest mode: the penalty per length times a segment, with unit masses.
                h = 2 * math.sin(math.pi / (6 * args.rings))
                runs.append(fire(p, s, args.tol, args.fire_max, 0.2 / math.sqrt(args.penalty * h + 4 * args.E)))
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(timeout=30)
    print(f"{p.n} nodes ({args.rings} rings per disk), tol {args.tol:g}")
    print(f"{'method':>7} {'iterations':>10} {'calls':>7} {'residual':>10} {'converged':>9} {'seconds':>8}")
    for r in runs:
        print(f"{r['method']:>7} {r['iterations']:>10} {r['calls']:>7} {r['residual']:>10.2e} {str(r['converged']):>9} "
              f"{r['seconds']:>8.2f}")
    print("newton residual history: " + " ".join(f"{x:.2e}" for x in runs[0]["history"]))
    if len(runs) > 1:
        diff = float(np.abs(runs[0]["u"] - runs[1]["u"]).max())
        print(f"largest difference between the two solutions: {diff:.2e}")
    if args.json:
        Path(args.json).write_text(json.dumps([{k: v for k, v in r.items() if k != "u"} for r in runs], indent=1))
    return 0 if all(r["converged"] for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
