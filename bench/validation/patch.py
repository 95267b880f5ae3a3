"""The FEM contact patch test: two elastic blocks of equal width stacked with flush sides,
the upper block's top under a uniform pressure p, the lower block's bottom on rollers.

The exact solution is uniform: sigma_yy = -p, sigma_xx = tau_xy = 0 in both blocks, and
the interface carries the traction p everywhere, corners included. The blocks are meshed
independently (non-matching interface meshes when the cell counts differ). The contact
surfaces (docs/model.md §13) are the upper block's bottom edge and the lower block's top
edge; one-pass makes the lower block a `master` (only the upper's nodes are slaves),
two-pass leaves both `both`. The lower block's bottom is held in y (and its left corner in
x), the upper block's top-left node in x: a frictionless interface leaves the upper block
free to slide otherwise. Same material in both blocks (so their sides stay flush).

Measured: the largest stress error over every element of both blocks,
max |sigma - sigma_exact| / p (each of sigma_xx, sigma_yy, tau_xy), and the largest
interface traction error, max |F_i / l_i - p| / p over the interface nodes of both blocks
(F_i the y component of the node's whole contact force: its own slave force and the
reactions of the other block's slaves on it; l_i its tributary length on the interface).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List

import numpy as np
from skfem.models.elasticity import lame_parameters

from fem import Array, Elastic, Loads, Model, block_mesh, boundary_segments, coupled, newton


@dataclass
class PatchRun:
    nlo: int                  # the lower block's cells along the interface (and up its height)
    nup: int                  # the upper block's
    passes: int               # 1: the lower block is a master; 2: both blocks are slaves and masters
    eps_ratio: float          # penalty * width / E* (the rule's eps a / E* with a = the width)
    alpha: float = 0.0        # both blocks' own smoothing
    surfaces: bool = True     # the interface edges as contact surfaces; False: the whole boundaries
    width: float = 1.0
    E: float = 1.0
    nu: float = 0.3
    p: float = 0.01           # the pressure on the top
    tol: float = 1e-8         # largest residual force, relative to p h (the round-off floor is about 1e-10)
    # results
    nodes: int = 0
    stress_err: float = 0.0         # max |sigma - exact| / p over the elements of both blocks
    stress_err_far: float = 0.0     # the same, over the elements farther than a quarter width from the interface
    traction_err: float = 0.0       # max |F_i / l_i - p| / p over the interface nodes of both blocks
    corner_traction: List[float] = field(default_factory=list)   # F_i / l_i / p at the four interface corners
    iterations: int = 0
    converged: bool = False
    contacts: int = 0

    @property
    def E_star(self) -> float:
        return self.E / (1.0 - self.nu ** 2)

    @property
    def h(self) -> float:
        """The finer interface mesh's element size."""
        return self.width / max(self.nlo, self.nup)

    def row(self) -> Dict[str, Any]:
        return {k: getattr(self, k) for k in ("nlo", "nup", "passes", "eps_ratio", "alpha", "surfaces", "nodes",
                                              "stress_err", "stress_err_far", "traction_err", "corner_traction",
                                              "iterations", "converged", "contacts")}


def element_stresses(body: Elastic, u: Array) -> Array:
    """Each element's (sigma_xx, sigma_yy, tau_xy) of a P1 displacement u (n, 2), plane strain."""
    lam, mu = lame_parameters(body.E, body.nu)
    p = body.mesh.p.T[body.mesh.t.T]                 # (m, 3, 2)
    d = u[body.mesh.t.T]                             # (m, 3, 2)
    # the gradient of the linear field through the three nodes: solve [x1-x0, x2-x0]^T G = [d1-d0, d2-d0]
    A = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=1)      # (m, 2, 2): rows are edge vectors
    B = np.stack([d[:, 1] - d[:, 0], d[:, 2] - d[:, 0]], axis=1)      # (m, 2, 2)
    G = np.linalg.solve(A, B)                        # G[k, i, j] = d u_j / d x_i
    exx, eyy, gxy = G[:, 0, 0], G[:, 1, 1], G[:, 1, 0] + G[:, 0, 1]
    tr = exx + eyy
    return np.stack([lam * tr + 2 * mu * exx, lam * tr + 2 * mu * eyy, mu * gxy], axis=1)


def solve(client: Any, run: PatchRun) -> PatchRun:
    W = run.width
    lo_mesh = block_mesh(0.0, 0.0, W, W, run.nlo, run.nlo)
    up_mesh = block_mesh(0.0, W, W, W, run.nup, run.nup)
    lo_fields: Dict[str, Any] = {"alpha": run.alpha}
    up_fields: Dict[str, Any] = {"alpha": run.alpha}
    if run.surfaces:
        lo_fields["surface"] = boundary_segments(lo_mesh, lambda x, y: np.isclose(y, W)).tolist()
        up_fields["surface"] = boundary_segments(up_mesh, lambda x, y: np.isclose(y, W)).tolist()
    if run.passes == 1:
        lo_fields["role"] = "master"
    lower = Elastic("lower", lo_mesh, run.E, run.nu, lo_fields)
    upper = Elastic("upper", up_mesh, run.E, run.nu, up_fields)
    eps = run.eps_ratio * run.E_star / W
    model = Model([lower, upper], penalty=eps)
    run.nodes = model.n
    X = model.X
    lo, up = model.nodes("lower"), model.nodes("upper")
    # supports: the lower block's bottom on rollers, its bottom-left corner and the upper's
    # top-left node held in x
    held: Dict[int, float] = {}
    for k in lo[np.isclose(X[lo, 1], 0.0)]:
        held[2 * int(k) + 1] = 0.0
    held[2 * int(lo[np.argmin(np.hypot(X[lo, 0], X[lo, 1]))])] = 0.0
    held[2 * int(up[np.argmin(np.hypot(X[up, 0], X[up, 1] - 2 * W))])] = 0.0
    # the pressure on the upper block's top: each top edge's p L / 2 on its two nodes
    f = np.zeros(2 * model.n)
    top = boundary_segments(up_mesh, lambda x, y: np.isclose(y, 2 * W)) + model.offset["upper"]
    for i, j in top:
        half = 0.5 * run.p * float(np.linalg.norm(X[j] - X[i]))
        f[2 * i + 1] -= half
        f[2 * j + 1] -= half
    loads = Loads.make(model, held, f)
    # start with the upper block 1.5 times its expected penetration into the lower (p / (passes eps)):
    # without a contact nothing holds it vertically
    u0 = np.zeros(2 * model.n)
    u0[2 * up + 1] = -1.5 * run.p / (run.passes * eps)
    with coupled(client, model) as contact:
        s = newton(model, contact, loads, u0, tol=run.tol * run.p * run.h, pressure=True)
    run.iterations, run.converged, run.contacts = s.iterations, s.converged, s.state.contacts
    U = s.u.reshape(-1, 2)
    exact = np.array([0.0, -run.p, 0.0])
    far = []
    errs = []
    for body, g in ((lower, lo), (upper, up)):
        sig = element_stresses(body, U[g])
        e = np.abs(sig - exact).max(axis=1) / run.p
        errs.append(e.max())
        centroid_y = body.mesh.p[1, body.mesh.t].mean(axis=0)
        far.append(e[np.abs(centroid_y - W) > 0.25 * W].max())
    run.stress_err, run.stress_err_far = float(max(errs)), float(max(far))
    # interface tractions: the whole contact force on each interface node over its interface length
    F = s.state.f.reshape(-1, 2)
    trac: List[float] = []
    corners: List[float] = []
    for g in (lo, up):
        on = g[np.isclose(X[g, 1], W)]
        xs = X[on, 0]
        order = np.argsort(xs)
        on, xs = on[order], xs[order]
        l = np.zeros(len(on))
        l[1:] += 0.5 * np.diff(xs)
        l[:-1] += 0.5 * np.diff(xs)
        t = np.abs(F[on, 1]) / l / run.p
        trac.extend(np.abs(t - 1.0).tolist())
        corners += [float(t[0]), float(t[-1])]
    run.traction_err = float(max(trac))
    run.corner_traction = corners
    return run


RULE = 500.0
"""The patch test's penalty: eps = RULE E* / h, h the finer interface cell (docs/validation.md §4)."""


def at_rule(nlo: int, nup: int, passes: int, factor: float = RULE, **kw: Any) -> PatchRun:
    """A run at eps = factor E* / h: eps W / E* = factor W / h."""
    return PatchRun(nlo, nup, passes, factor * max(nlo, nup), **kw)
