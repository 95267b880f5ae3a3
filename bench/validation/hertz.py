"""Hertz contact in 2D (plane strain cylinders): an elastic disk on a rigid flat, and two
equal elastic disks, against a = sqrt(4 P R* / (pi E*)), p0 = 2 P / (pi a).

The load: a point load P (per unit thickness) at the top of the (upper) disk, in equal
steps; the x of the nodes on the vertical axis through the load (top and centre) is held,
which removes the two rigid modes a frictionless contact leaves free without loading
anything (the problem is symmetric). For two disks the lower disk's bottom node is held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, List

import numpy as np

from fem import (Array, Elastic, Loads, Model, Rigid, coupled, graded_disk, mirrored, newton,
                 surface_spacing)


def e_star(kind: str, E: float, nu: float) -> float:
    """1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2: a rigid flat ("flat") adds nothing, an equal
    disk ("disks") as much again."""
    e = E / (1.0 - nu ** 2)
    return e if kind == "flat" else e / 2.0


def r_star(kind: str, R: float) -> float:
    """1/R* = 1/R1 + 1/R2: the flat's radius is infinite."""
    return R if kind == "flat" else R / 2.0


def load_for(a: float, R_star: float, E_star: float) -> float:
    """The load P (per unit thickness) of half-width a: a = sqrt(4 P R* / (pi E*))."""
    return math.pi * a * a * E_star / (4.0 * R_star)


def peak(P: float, a: float) -> float:
    """p0 = 2 P / (pi a): p(x) = p0 sqrt(1 - x^2 / a^2)."""
    return 2.0 * P / (math.pi * a)


class HertzGeometry:
    """What a run's Hertz contact gives (kind, E, nu, R, the contact half-width
    a and the element size h at it): E*, R* and a/h; HertzRun's and the
    Cattaneo-Mindlin runs' (mindlin.py)."""

    kind: str
    E: float
    nu: float
    R: float
    a: float
    h: float

    @property
    def E_star(self) -> float:
        return e_star(self.kind, self.E, self.nu)

    @property
    def R_star(self) -> float:
        return r_star(self.kind, self.R)

    @property
    def a_h(self) -> float:
        return self.a / self.h


@dataclass
class HertzRun(HertzGeometry):
    kind: str                 # "flat" (disk on a rigid flat) or "disks" (two equal disks)
    a_R: float                # target a / R
    levels: int               # refinement levels of the graded disk: h = 2 R sin(pi / 2^(levels + 2))
    eps_ratio: float          # penalty * a / E*
    R: float = 1.0
    E: float = 1.0
    nu: float = 0.3
    steps: int = 5
    alpha: float = 0.0        # the disks' own smoothing (the flat's is 0)
    zone: float = 1.3         # the fine zone: |x| <= zone a on the surface, down to depth a below it,
    depth: float = 0.5        # elements growing by `grading` times their distance beyond
    grading: float = 12.0
    background: int = 3       # init_circle's uniform refinements
    turn: float = 45.0        # 0: the contact centre on one of init_circle's first corners
    # results
    nodes: int = 0
    h: float = 0.0
    P: float = 0.0
    a: float = 0.0            # Hertz
    p0: float = 0.0
    a_fem: float = 0.0        # from the nodal forces: a^2 = 4 sum F x^2 / sum F
    p0_fem: float = 0.0       # the largest nodal pressure
    profile_mid: float = 0.0  # max |p_i - p_H(x_i)| / p0 over the nodes with |x| <= 0.8 a
    profile_rms: float = 0.0  # RMS of (p_i - p_H(x_i)) / p0 over the nodes with |x| < a
    pressure_share: float = 0.0    # sum of the pressure output times l over sum F_y (see below)
    iterations: List[int] = field(default_factory=list)
    calls: int = 0
    converged: bool = False
    x: Array = field(default_factory=lambda: np.zeros(0))
    p: Array = field(default_factory=lambda: np.zeros(0))

    @property
    def err_a(self) -> float:
        return self.a_fem / self.a - 1.0

    @property
    def err_p0(self) -> float:
        return self.p0_fem / self.p0 - 1.0

    def row(self) -> Dict[str, Any]:
        return {k: getattr(self, k) for k in ("kind", "a_R", "a_h", "eps_ratio", "nodes", "P", "a", "p0", "a_fem",
                                              "p0_fem", "err_a", "err_p0", "profile_mid", "profile_rms",
                                              "pressure_share", "iterations", "calls", "converged")}


def solve(client: Any, run: HertzRun) -> HertzRun:
    R = run.R
    a = run.a_R * R
    run.a = a
    run.P = load_for(a, run.R_star, run.E_star)
    run.p0 = peak(run.P, a)
    eps = run.eps_ratio * run.E_star / a
    mesh = graded_disk(R, surface_spacing(R, run.levels), zone=run.zone * a, depth=run.depth * a, grading=run.grading,
                       background=run.background, turn=run.turn, centre=(0.0, R))
    upper = Elastic("upper", mesh, run.E, run.nu, {"alpha": run.alpha})
    e = upper.boundary_edges()
    mid = 0.5 * (upper.nodes[e[:, 0]] + upper.nodes[e[:, 1]])
    zone = (np.abs(mid[:, 0]) <= a) & (mid[:, 1] < R)
    run.h = float(np.linalg.norm(upper.nodes[e[zone, 1]] - upper.nodes[e[zone, 0]], axis=1).max())
    if run.kind == "flat":
        lower: Any = Rigid("flat", np.array([[-2 * R, -R], [2 * R, -R], [2 * R, 0.0], [-2 * R, 0.0]]))
    else:
        lower = Elastic("lower", mirrored(mesh), run.E, run.nu, {"alpha": run.alpha})
    model = Model([upper, lower], penalty=eps)
    run.nodes = model.n
    X = model.X

    def at(name: str, x: float, y: float) -> int:
        g = model.nodes(name)
        k = int(g[np.argmin(np.hypot(X[g, 0] - x, X[g, 1] - y))])
        assert math.hypot(X[k, 0] - x, X[k, 1] - y) < 1e-12 * R, (name, x, y)
        return k

    top, centre = at("upper", 0.0, 2 * R), at("upper", 0.0, R)
    held = {2 * top: 0.0, 2 * centre: 0.0}
    if run.kind == "flat":
        held.update({int(d): 0.0 for d in model.rigid_dofs()})
    else:
        bottom, centre_b = at("lower", 0.0, -2 * R), at("lower", 0.0, -R)
        held.update({2 * bottom: 0.0, 2 * bottom + 1: 0.0, 2 * centre_b: 0.0})
    l = model.tributary_lengths()
    up = model.nodes("upper")
    u = np.zeros(2 * model.n)
    # The first step starts from the upper disk moved down by the geometric interference of
    # that step's contact (a^2 / (2 R*)): without a contact, nothing holds it vertically.
    a1 = a * math.sqrt(1.0 / run.steps)
    u[2 * up + 1] = -a1 * a1 / (2.0 * run.R_star)
    with coupled(client, model) as contact:
        for k in range(1, run.steps + 1):
            f = np.zeros(2 * model.n)
            f[2 * top + 1] = -run.P * k / run.steps
            last = k == run.steps
            s = newton(model, contact, Loads.make(model, held, f), u, tol=1e-10 * run.P, pressure=last)
            run.iterations.append(s.iterations)
            run.converged = (k == 1 or run.converged) and s.converged
            u = s.u
        run.calls = contact.calls
    fy = s.state.f[2 * up + 1]
    c = up[fy > 0]
    x, F = X[c, 0], fy[fy > 0]
    order = np.argsort(x)
    x, F = x[order], F[order]
    run.x, run.p = x, F / l[c[order]]
    run.a_fem = 2.0 * math.sqrt(float(F @ x ** 2) / float(F.sum()))
    run.p0_fem = float(run.p.max())
    ph = run.p0 * np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None))
    mid = np.abs(x) <= 0.8 * a
    inside = np.abs(x) < a
    run.profile_mid = float(np.abs(run.p[mid] - ph[mid]).max()) / run.p0
    run.profile_rms = float(np.sqrt(np.mean((run.p[inside] - ph[inside]) ** 2))) / run.p0
    assert s.state.pressure is not None
    # The pressure output (docs/model.md (21)) counts a node's own slave forces only: with a
    # rigid master that is all of its contact force; between two disks (both slaves and masters)
    # about half, the other half being the reactions of the other disk's slaves.
    run.pressure_share = float(s.state.pressure[c] @ l[c]) / float(F.sum())
    return run
