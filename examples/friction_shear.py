#!/usr/bin/env python3
"""Coulomb friction in an implicit solver: an elastic disk pressed on a rigid
block, then sheared until it slides.

A linear-elastic disk (plane strain, linear triangles; the assembly of
examples/newton_disks.py) rests on a rigid block (a `master` body with alpha
0). Its centre is pushed down by --press in load steps, then its centre and
top node are moved sideways together (so that it slides and does not roll) in
--steps shear steps. The contact has Coulomb friction with history
(docs/model.md §14): the session keeps the anchors, every Newton iteration is
a trial from the last committed ones (`commit=False`), and each converged
load step is committed (docs/coupling.md §6). The tangent is the consistent
one, not symmetric in slip; the line search is on the residual (friction
dissipates: there is no energy to minimise).

Each load step prints the Newton iterations, the normal load P and the
tangential load Q on the block (the sums of the contact forces), Q / (mu P),
the contacts sticking and slipping, and the work dissipated. Once every
contact slips, Q = mu P.

    .venv/bin/python examples/friction_shear.py [--rings 16] [--mu 0.3] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "clients" / "python" / "src"))
sys.path.insert(0, str(REPO / "examples"))
import ntscontact  # noqa: E402
from ntscontact.mesh import disk_mesh  # noqa: E402
from newton_disks import elastic_stiffness, start_daemon  # noqa: E402

OUTPUTS = ["forces", "stiffness"]


class Problem:
    """The disk (radius 1, centre (0, 1): it touches the block's top y = 0) and
    the block; global node order: the disk's nodes, then the block's 4."""

    def __init__(self, rings: int, E: float, nu: float, mu: float, penalty: float, alpha: float) -> None:
        d, t = disk_mesh(1.0, rings, 0.0, 1.0)
        block = np.array([[-3.0, -1.0], [3.0, -1.0], [3.0, 0.0], [-3.0, 0.0]])
        self.scene = ntscontact.Scene(penalty=penalty, alpha=alpha, penalty_scaling="length", search_radius=0.05,
                                      friction=mu, outputs=OUTPUTS)
        self.scene.add_body(d, triangles=t, id="disk")
        self.scene.add_body(block, id="block", alpha=0.0, role="master")
        self.X = self.scene.positions().ravel().copy()
        self.nd = len(d)
        self.n = len(d) + 4
        self.K = sp.block_diag([elastic_stiffness(d, t, E, nu), sp.csr_matrix((8, 8))]).tocsr()
        centre = int(np.argmin(np.hypot(d[:, 0], d[:, 1] - 1.0)))
        top = int(np.argmax(d[:, 1]))
        # prescribed: the block, the centre (x, y) and the top node's x (no rolling)
        self.block = np.arange(2 * self.nd, 2 * self.n)
        self.moved_x = np.array([2 * centre, 2 * top])
        self.moved_y = np.array([2 * centre + 1])
        self.fixed = np.concatenate([self.block, self.moved_x, self.moved_y])
        self.free = np.setdiff1d(np.arange(2 * self.n), self.fixed)


def solve_step(p: Problem, s: Any, u: np.ndarray, tol: float, max_iter: int) -> Dict[str, Any]:
    """Newton on R(u) = K u - f_contact(u) = 0 over the free dofs, every
    evaluation a trial from the committed anchors; then the commit."""
    history: List[float] = []
    res = s.step((p.X + u).reshape(-1, 2), commit=False, outputs=OUTPUTS)
    for it in range(max_iter + 1):
        r = p.K @ u - res.force_array().ravel()
        norm = float(np.abs(r[p.free]).max())
        history.append(norm)
        if norm < tol or it == max_iter:
            break
        J = (p.K + res.stiffness).tocsr()[p.free][:, p.free]
        du = np.zeros_like(u)
        du[p.free] = spla.spsolve(J.tocsc(), -r[p.free])
        t = 1.0
        for _ in range(30):  # backtracking on the residual's norm
            trial = s.step((p.X + u + t * du).reshape(-1, 2), commit=False, outputs=OUTPUTS)
            rt = p.K @ (u + t * du) - trial.force_array().ravel()
            if float(np.abs(rt[p.free]).max()) < (1 - 1e-4 * t) * norm or t < 1e-6:
                break
            t *= 0.5
        u, res = u + t * du, trial
    done = s.step((p.X + u).reshape(-1, 2), outputs=OUTPUTS)  # commit: the converged anchors are the history
    f = done.force_array()
    block = f[p.nd:]
    return {"u": u, "iterations": len(history) - 1, "residual": history[-1], "converged": history[-1] < tol,
            "P": float(-block[:, 1].sum()), "Q": float(block[:, 0].sum()), "contacts": done.summary.contacts,
            "sticking": done.summary.sticking, "slipping": done.summary.slipping,
            "dissipation": done.summary.dissipation, "history": history}


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", help="a running ntscontactd (default: start one from the build dir)")
    ap.add_argument("--build-dir", default=os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))
    ap.add_argument("--rings", type=int, default=16, help="mesh rings of the disk (1 + 3 r (r + 1) nodes)")
    ap.add_argument("--E", type=float, default=100.0)
    ap.add_argument("--nu", type=float, default=0.3)
    ap.add_argument("--mu", type=float, default=0.3, help="Coulomb's coefficient")
    ap.add_argument("--penalty", type=float, default=1e5, help="per unit length (normal and tangential)")
    ap.add_argument("--alpha", type=float, default=0.2)
    ap.add_argument("--press", type=float, default=0.08, help="how far the centre is pushed down")
    ap.add_argument("--press-steps", type=int, default=4)
    ap.add_argument("--shear", type=float, default=0.16, help="how far the centre and top move sideways")
    ap.add_argument("--steps", type=int, default=8, help="shear load steps")
    ap.add_argument("--tol", type=float, default=1e-8, help="largest residual force")
    ap.add_argument("--max-iter", type=int, default=40)
    ap.add_argument("--json", help="write the load steps as JSON")
    args = ap.parse_args(argv)
    p = Problem(args.rings, args.E, args.nu, args.mu, args.penalty, args.alpha)
    loads = [(0.0, -args.press * (k + 1) / args.press_steps) for k in range(args.press_steps)]
    loads += [(args.shear * (k + 1) / args.steps, -args.press) for k in range(args.steps)]
    proc, url = (None, args.url) if args.url else start_daemon(Path(args.build_dir))
    steps: List[Dict[str, Any]] = []
    try:
        with ntscontact.Client(url, timeout=120.0) as client, client.session(p.scene) as s:
            u = np.zeros(2 * p.n)
            for ux, uy in loads:
                u[p.moved_x], u[p.moved_y] = ux, uy
                step = solve_step(p, s, u, args.tol, args.max_iter)
                u = step.pop("u")
                steps.append(dict(step, shear=ux, press=-uy))
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(timeout=30)
    print(f"{p.n} nodes ({args.rings} rings), mu {args.mu:g}, tol {args.tol:g}")
    print(f"{'shear':>7} {'press':>6} {'iter':>4} {'P':>9} {'Q':>9} {'Q/(mu P)':>9} {'stick':>5} {'slip':>4} "
          f"{'dissipated':>10}")
    for st in steps:
        ratio = st["Q"] / (args.mu * st["P"]) if st["P"] > 0 else 0.0
        print(f"{st['shear']:>7.4f} {st['press']:>6.3f} {st['iterations']:>4d} {st['P']:>9.4f} {st['Q']:>9.4f} "
              f"{ratio:>9.6f} {st['sticking']:>5d} {st['slipping']:>4d} {st['dissipation']:>10.3e}")
    if args.json:
        Path(args.json).write_text(json.dumps({"mu": args.mu, "steps": steps}, indent=1))
    return 0 if all(st["converged"] for st in steps) else 1


if __name__ == "__main__":
    sys.exit(main())
