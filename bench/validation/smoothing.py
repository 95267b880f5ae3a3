"""Why smoothing: an elastic block pressed onto a rigid 24-gon and dragged back and forth.

The block's top is prescribed: pressed down by `indent`, then moved horizontally by d, from
0 to -D (preparation), -D to +D and back to -D (the loop). The 24-gon (a vertex at the top)
is a rigid master whose own alpha is the smoothing under test; the block is its slave.
Frictionless, so the driver's work over the closed loop, W = loop integral of F_x dd, is 0
for a path-independent (conservative, single-valued) response.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Tuple

import numpy as np

from fem import Array, Elastic, Loads, Model, Rigid, block_mesh, coupled, fire, newton, regular_polygon


@dataclass
class DragRun:
    alpha: float              # the 24-gon's own smoothing
    nx: int = 40              # block cells along x (h = width / nx on the sliding face)
    ny: int = 10
    width: float = 1.0
    height: float = 0.25
    R: float = 1.0            # the 24-gon's circumradius
    sides: int = 24
    E: float = 1.0
    nu: float = 0.3
    penalty: float = 1e3      # per length (a pressure stiffness)
    indent: float = 0.01      # the top's downward displacement
    D: float = 0.2            # the stroke: d from -D to +D
    per_node: int = 8         # drag steps per node spacing h
    fire_positions: int = 4   # positions d = k h / fire_positions where FIRE and Newton are compared
                              # (d = 0: a node of the block right above the 24-gon's top vertex)
    tol: float = 1e-9         # largest residual force (the normal load is about 1e-2)
    # results
    d: Array = field(default_factory=lambda: np.zeros(0))          # the loop's positions
    Fx: Array = field(default_factory=lambda: np.zeros(0))         # the driver's horizontal force
    Fy: Array = field(default_factory=lambda: np.zeros(0))         # the driver's vertical force (down < 0)
    iterations: List[int] = field(default_factory=list)            # Newton iterations per loop step
    calls: int = 0
    all_converged: bool = False
    work: float = 0.0                                              # the loop's work
    mu: float = 0.0                                                # W / (mean N * 4 D)
    path_gap: float = 0.0     # max over d of |u(d) forward - u(d) backward| / indent (largest node)
    jump_deg: float = 0.0     # the largest change of a node's force direction between two steps
    track: Array = field(default_factory=lambda: np.zeros((0, 2)))  # (d, angle) of one node's force
    fire_gap: List[float] = field(default_factory=list)            # |u_newton - u_fire| / indent, per position
    fire_iterations: List[int] = field(default_factory=list)
    fire_newton_iterations: List[int] = field(default_factory=list)
    fire_energy: List[Tuple[float, float]] = field(default_factory=list)   # Pi of (Newton, FIRE)
    fire_converged: bool = False

    @property
    def h(self) -> float:
        return self.width / self.nx

    def row(self) -> Dict[str, Any]:
        it = np.array(self.iterations)
        return {"alpha": self.alpha, "h": self.h, "work": self.work, "mu": self.mu, "path_gap": self.path_gap,
                "jump_deg": self.jump_deg, "newton_mean": float(it.mean()), "newton_max": int(it.max()),
                "newton_total": int(it.sum()), "calls": self.calls, "all_converged": self.all_converged,
                "fire_gap_max": max(self.fire_gap) if self.fire_gap else float("nan"),
                "fire_iterations": self.fire_iterations, "fire_newton_iterations": self.fire_newton_iterations,
                "fire_converged": self.fire_converged}


def solve(client: Any, run: DragRun) -> DragRun:
    top_y = run.R + run.height
    block = Elastic("block", block_mesh(-run.width / 2, run.R, run.width, run.height, run.nx, run.ny), run.E, run.nu)
    gon = Rigid("gon", regular_polygon(run.R, run.sides), {"role": "master", "alpha": run.alpha})
    model = Model([block, gon], penalty=run.penalty, alpha=0.0)
    X = model.X
    b = model.nodes("block")
    top = b[np.abs(X[b, 1] - top_y) < 1e-12]
    bottom = b[np.abs(X[b, 1] - run.R) < 1e-12]
    bottom = bottom[np.argsort(X[bottom, 0])]
    rigid = {int(k): 0.0 for k in model.rigid_dofs()}

    def loads(d: float, indent: float) -> Loads:
        held = dict(rigid)
        held.update({int(2 * k): d for k in top})
        held.update({int(2 * k + 1): -indent for k in top})
        return Loads.make(model, held)

    def driver(s: Any, ld: Loads) -> Array:
        r = s.reaction(model, ld)
        return np.array([r[2 * top].sum(), r[2 * top + 1].sum()])

    def angles(f: Array) -> Array:
        fb = f.reshape(-1, 2)[bottom]
        ang = np.degrees(np.arctan2(fb[:, 0], fb[:, 1]))
        return np.where(np.hypot(fb[:, 0], fb[:, 1]) > 0, ang, np.nan)

    h = run.h
    step = h / run.per_node
    n_prep, n_loop = int(round(run.D / step)), int(round(2 * run.D / step))
    ds = np.concatenate([np.linspace(0, -run.D, n_prep + 1)[1:], np.linspace(-run.D, run.D, n_loop + 1)[1:],
                         np.linspace(run.D, -run.D, n_loop + 1)[1:]])
    u = np.zeros(2 * model.n)
    with coupled(client, model) as contact:
        for k in range(1, 5):                                    # press at d = 0
            s = newton(model, contact, loads(0.0, run.indent * k / 4), u, run.tol)
            u = s.u
        d_loop: List[float] = [-run.D]
        states: List[Array] = []
        F: List[Array] = []
        ang: List[Array] = []
        iters: List[int] = []
        conv = True
        for i, d in enumerate(ds):
            ld = loads(float(d), run.indent)
            s = newton(model, contact, ld, u, run.tol)
            conv &= s.converged
            u = s.u
            if i == n_prep - 1:                                  # the loop starts here, at -D
                states, F, ang = [u], [driver(s, ld)], [angles(s.state.f)]
            elif i >= n_prep:
                d_loop.append(float(d))
                states.append(u)
                F.append(driver(s, ld))
                ang.append(angles(s.state.f))
                iters.append(s.iterations)
        run.calls = contact.calls
        run.all_converged = bool(conv)
        run.d, run.iterations = np.array(d_loop), iters
        Fa = np.array(F)
        run.Fx, run.Fy = Fa[:, 0], Fa[:, 1]
        run.work = float(np.sum(0.5 * (run.Fx[1:] + run.Fx[:-1]) * np.diff(run.d)))
        run.mu = run.work / (float(np.mean(np.abs(run.Fy))) * 4 * run.D)
        # Forward state k and backward state 2 n_loop - k are at the same d.
        U = np.array(states)
        gaps = [np.hypot(*(U[k] - U[2 * n_loop - k]).reshape(-1, 2).T).max() for k in range(n_loop + 1)]
        run.path_gap = float(max(gaps)) / run.indent
        A = np.array(ang)
        both = ~np.isnan(A[1:]) & ~np.isnan(A[:-1])
        run.jump_deg = float(np.abs(np.where(both, A[1:] - A[:-1], 0.0)).max())
        # The node that passes over the 24-gon's top vertex at d = 0 during the forward sweep.
        j = int(np.argmin(np.abs(X[bottom, 0])))
        run.track = np.stack([run.d[:n_loop + 1], A[:n_loop + 1, j]], axis=1)
        # FIRE against Newton from the same start (the block squeezed uniformly, its bottom
        # untouched) at positions spread over one node spacing.
        ok = True
        for d in np.linspace(0.0, h, run.fire_positions, endpoint=False):
            ld = loads(float(d), run.indent)
            u0 = np.zeros(2 * model.n)
            u0[2 * b] = d
            u0[2 * b + 1] = -run.indent * (X[b, 1] - run.R) / run.height
            sn = newton(model, contact, ld, u0, run.tol)
            sf = fire(model, contact, ld, u0, run.tol)
            ok &= sn.converged and sf.converged
            run.fire_gap.append(float(np.hypot(*(sn.u - sf.u).reshape(-1, 2).T).max()) / run.indent)
            run.fire_iterations.append(sf.iterations)
            run.fire_newton_iterations.append(sn.iterations)
            run.fire_energy.append((sn.energy, sf.energy))
        run.fire_converged = bool(ok)
    return run
