"""The FEM side of the validation cases, shared by all of them.

- meshes: a disk graded towards a contact zone (and a half-disk, the same
  way), a block (also the patch test's), a regular polygon (a rigid obstacle);
- bodies: `Elastic` (a scikit-fem P1 mesh, plane-strain linear elasticity
  assembled by scikit-fem) and `Rigid` (a loop of nodes, every dof held);
  each carries `fields`, extra members of its body in the scene document
  (`alpha`, `role`, and any field the core gains, e.g. a contact surface);
- `Model`: the bodies in one global numbering (the scene's: bodies in order,
  nodes in body order, dof 2 node + component), the elastic stiffness, the
  scene document;
- `Contact`: one session of ntscontactd (binary steps) giving the contact
  forces, energy, tangent and pressure at a displacement (with friction, a
  trial step or a committed one);
- `newton` (consistent tangent, backtracking line search on the total energy)
  and `fire` (forces only), both on Pi(u) = 1/2 u.K u - f.u + E_contact(X + u)
  with prescribed dofs held at their values;
- `Tied` (groups of nodes moving as one rigid translation: a bonded platen)
  and `newton_friction` (one load increment with friction: Newton with the
  non-symmetric tangent, a line search on the residual, trial steps committed
  at convergence);
- `service`: ntscontactd started from the build directory on a free port.
"""

from __future__ import annotations

import contextlib
import math
import re
import select
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from skfem import Basis, ElementTriP1, ElementVector, MeshTri, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "clients" / "python" / "src"))
import ntscontact  # noqa: E402

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


# ------------------------------------------------------------------ meshes


def _sizes(m: MeshTri) -> Array:
    """Element size: the longest edge over sqrt 2 (a right isosceles triangle's leg)."""
    p = m.p[:, m.t]
    e = [np.hypot(*(p[:, (k + 1) % 3] - p[:, k])) for k in range(3)]
    return np.maximum(np.maximum(e[0], e[1]), e[2]) / math.sqrt(2.0)


def graded_disk(radius: float, h: float, zone: float, depth: float, grading: float = 3.0,
                centre: Tuple[float, float] = (0.0, 0.0), background: int = 3, turn: float = 45.0) -> MeshTri:
    """A disk meshed finely (element size `h`) towards its lowest point.

    Starts from scikit-fem's `MeshTri.init_circle(background)` (4 * 2^background boundary
    segments; turned by `turn` degrees) and refines locally (`refined(marked)`, conforming) every element larger
    than `h` whose distance to the fine zone is below `grading` times its size;
    new boundary nodes are moved onto the circle after each pass (they bisect
    the arcs, so the boundary spacing is exactly 2 R sin(pi / 2^(L+2)) after
    L levels). The fine zone is the part of the disk within `depth` of the arc
    |x| <= `zone` at the bottom. Elements grow geometrically away from it."""
    m = MeshTri.init_circle(background, smoothed=True)
    # Turned by 45 degrees: the lowest point is then a node made by bisecting an arc, in the
    # regular pattern of the refinement, not one of the four corners of init_circle's first
    # mesh (`turn` 0), around which the pattern is irregular (docs/validation.md §1).
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    m = MeshTri(np.array([[c, -s], [s, c]]) @ m.p, m.t)
    m = _refine_towards_bottom(m, radius, h, zone, depth, grading, lambda p, b: b)
    return MeshTri(m.p * radius + np.asarray(centre, dtype=float)[:, None], m.t)


def _refine_towards_bottom(m: MeshTri, radius: float, h: float, zone: float, depth: float, grading: float,
                           on_arc: Any) -> MeshTri:
    """`graded_disk`'s local refinement of a mesh of the unit disk (or part of it) towards its
    lowest point: every element larger than `h` whose distance to the fine zone is below
    `grading` times its size is refined (conforming), and the new boundary nodes that
    `on_arc(p, boundary_nodes)` selects are moved onto the unit circle after each pass."""
    th = math.asin(min(zone / radius, 1.0))
    end = np.array([radius * math.sin(th), -radius * math.cos(th)])
    while True:
        q = m.p[:, m.t].mean(axis=1) * radius
        r = np.hypot(q[0], q[1])
        below = np.abs(np.arctan2(q[0], -q[1])) <= th
        to_end = np.minimum(np.hypot(q[0] - end[0], q[1] - end[1]), np.hypot(q[0] + end[0], q[1] - end[1]))
        d = np.maximum(np.where(below, radius - r, to_end) - depth, 0.0)
        s = _sizes(m) * radius
        marked = np.flatnonzero((s > 1.01 * h) & (d < grading * s))
        if marked.size == 0:
            break
        m = m.refined(marked)
        p = m.p.copy()
        b = on_arc(p, m.boundary_nodes())
        p[:, b] /= np.hypot(p[0, b], p[1, b])
        m = MeshTri(p, m.t)
    return m


def graded_half_disk(radius: float, levels: int, zone: float, depth: float, grading: float = 3.0,
                     centre: Tuple[float, float] = (0.0, 0.0), background: int = 3) -> MeshTri:
    """The lower half of a disk (its flat edge through `centre`, its arc below), meshed finely
    towards its lowest point as `graded_disk` is, to `levels` bisections of the arc there.

    The seed is three equilateral triangles (the centre and the arc's nodes at 0, -60, -120
    and -180 degrees), refined uniformly `background` times (Laplacian smoothing, new arc
    nodes moved onto the circle: scikit-fem's `init_circle` recipe), then locally. The lowest
    point is made by bisecting the seed's middle arc, in the refinement's regular pattern
    (not a corner of the seed: docs/validation.md §1 on the irregular node). The arc
    spacing is exactly `half_disk_spacing(radius, L)` after L bisections. Element size is
    measured as in `graded_disk` (the longest edge over sqrt 2), but these elements are
    near-equilateral and those at the arc a little stretched by the projection: the size
    threshold is set halfway between `levels` and `levels - 1` bisections."""
    ang = np.radians([0.0, -60.0, -120.0, -180.0])
    p = np.concatenate([[[0.0], [0.0]], np.stack([np.cos(ang), np.sin(ang)])], axis=1)
    p[1, [1, 4]] = 0.0
    m = MeshTri(p, np.array([[0, 2, 1], [0, 3, 2], [0, 4, 3]]).T)

    def on_arc(q: Array, b: IntArray) -> IntArray:
        return b[q[1, b] < -1e-12]          # the flat edge's nodes stay where bisection put them

    for _ in range(background):
        m = m.refined().smoothed()
        q = m.p.copy()
        b = on_arc(q, m.boundary_nodes())
        q[:, b] /= np.hypot(q[0, b], q[1, b])
        m = MeshTri(q, m.t)
    h = 1.5 * half_disk_spacing(radius, levels) / (1.01 * math.sqrt(2.0))
    m = _refine_towards_bottom(m, radius, h, zone, depth, grading, on_arc)
    return MeshTri(m.p * radius + np.asarray(centre, dtype=float)[:, None], m.t)


def half_disk_spacing(radius: float, levels: int) -> float:
    """The arc spacing of `graded_half_disk` after `levels` bisections of its seed's 60-degree arcs."""
    return 2.0 * radius * math.sin(math.pi / (3 * 2 ** (levels + 1)))


def surface_spacing(radius: float, levels: int) -> float:
    """The boundary spacing of `graded_disk` after `levels` bisections of init_circle's 4 arcs."""
    return 2.0 * radius * math.sin(math.pi / 2 ** (levels + 2))


def mirrored(m: MeshTri, y0: float = 0.0) -> MeshTri:
    """The mirror image of a mesh about the line y = y0 (triangles kept counter-clockwise)."""
    p = m.p.copy()
    p[1] = 2.0 * y0 - p[1]
    return MeshTri(p, m.t[[0, 2, 1]])


def block_mesh(x0: float, y0: float, width: float, height: float, nx: int, ny: int) -> MeshTri:
    """A rectangle [x0, x0 + width] x [y0, y0 + height], nx x ny cells split into triangles
    (scikit-fem's init_tensor): the patch test's and the dragged block's mesh."""
    return MeshTri.init_tensor(np.linspace(x0, x0 + width, nx + 1), np.linspace(y0, y0 + height, ny + 1))


def boundary_segments(m: MeshTri, where: Optional[Any] = None) -> IntArray:
    """The boundary edges of a mesh as node-index pairs (i, j) running counter-clockwise
    (the body to the left), those whose midpoint satisfies `where(x, y)` (all when None):
    e.g. the top of a block, `lambda x, y: np.isclose(y, y_top)`. What a body's contact
    surface field (`"surface": [[i, j], ...]`, coming in the core) will list."""
    f = m.boundary_facets()
    e = m.facets[:, f]
    t = m.t[:, m.f2t[0, f]]
    third = t.sum(axis=0) - e[0] - e[1]                   # the element's node off the edge
    p0, p1, p2 = m.p[:, e[0]], m.p[:, e[1]], m.p[:, third]
    left = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0]) > 0
    pairs = np.where(left, e, e[::-1]).T.astype(np.int64)
    if where is not None:
        mid = 0.5 * (m.p[:, pairs[:, 0]] + m.p[:, pairs[:, 1]])
        pairs = pairs[np.asarray(where(mid[0], mid[1]), dtype=bool)]
    return pairs


def regular_polygon(radius: float, sides: int, centre: Tuple[float, float] = (0.0, 0.0),
                    vertex_angle: float = 90.0) -> Array:
    """The `sides` vertices of a regular polygon, counter-clockwise, one at `vertex_angle` degrees."""
    t = math.radians(vertex_angle) + 2.0 * math.pi * np.arange(sides) / sides
    return np.stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)], axis=1)


# ------------------------------------------------------------------ bodies


@dataclass
class Elastic:
    """A linear-elastic body (plane strain) on a P1 mesh. `fields` go into its scene body."""

    name: str
    mesh: MeshTri
    E: float
    nu: float
    fields: Dict[str, Any] = field(default_factory=dict)

    @property
    def nodes(self) -> Array:
        return np.ascontiguousarray(self.mesh.p.T)

    def stiffness(self) -> sp.csr_matrix:
        basis = Basis(self.mesh, ElementVector(ElementTriP1()))
        # scikit-fem numbers a vector P1 field's dofs 2 node + component, as the scene does.
        assert np.array_equal(basis.nodal_dofs[0], 2 * np.arange(self.mesh.p.shape[1]))
        return asm(linear_elasticity(*lame_parameters(self.E, self.nu)), basis).tocsr()

    def boundary_edges(self) -> IntArray:
        return np.asarray(self.mesh.facets[:, self.mesh.boundary_facets()].T, dtype=np.int64)

    def scene_body(self) -> Dict[str, Any]:
        return {"id": self.name, "nodes": self.nodes.tolist(), "triangles": self.mesh.t.T.tolist(), **self.fields}


@dataclass
class Rigid:
    """A rigid obstacle: one loop of nodes, every dof held. By default a master with its own alpha 0."""

    name: str
    points: Array
    fields: Dict[str, Any] = field(default_factory=lambda: {"role": "master", "alpha": 0.0})

    @property
    def nodes(self) -> Array:
        return np.asarray(self.points, dtype=np.float64)

    def stiffness(self) -> sp.csr_matrix:
        n = 2 * len(self.points)
        return sp.csr_matrix((n, n))

    def boundary_edges(self) -> IntArray:
        k = np.arange(len(self.points))
        return np.stack([k, np.roll(k, -1)], axis=1)

    def scene_body(self) -> Dict[str, Any]:
        return {"id": self.name, "nodes": self.nodes.tolist(), **self.fields}


Body = Union[Elastic, Rigid]


class Model:
    """Bodies in one global numbering (the scene's), the elastic stiffness K (2N x 2N), the
    scene document (penalty per length by default: `penalty` is a pressure stiffness)."""

    def __init__(self, bodies: Sequence[Body], penalty: float, alpha: float = 0.0,
                 options: Optional[Dict[str, Any]] = None) -> None:
        self.bodies = list(bodies)
        counts = [len(b.nodes) for b in self.bodies]
        self.offset = dict(zip((b.name for b in self.bodies), np.concatenate([[0], np.cumsum(counts)[:-1]])))
        self.X = np.concatenate([b.nodes for b in self.bodies])
        self.n = len(self.X)
        self.K = sp.block_diag([b.stiffness() for b in self.bodies], format="csr")
        opts = {"penalty": float(penalty), "alpha": float(alpha), "penalty_scaling": "length"}
        opts.update(options or {})
        self.scene: Dict[str, Any] = {"options": opts, "bodies": [b.scene_body() for b in self.bodies]}

    def body(self, name: str) -> Body:
        return next(b for b in self.bodies if b.name == name)

    def nodes(self, name: str, local: Optional[npt.ArrayLike] = None) -> IntArray:
        """Global node indices of body `name` (all, or its `local` ones)."""
        b = self.body(name)
        idx = np.arange(len(b.nodes)) if local is None else np.asarray(local, dtype=np.int64)
        return (self.offset[name] + idx).astype(np.int64)

    def dofs(self, name: str, local: Optional[npt.ArrayLike] = None, comps: Sequence[int] = (0, 1)) -> IntArray:
        g = self.nodes(name, local)
        return np.sort(np.concatenate([2 * g + c for c in comps]))

    def rigid_dofs(self) -> IntArray:
        return np.concatenate([self.dofs(b.name) for b in self.bodies if isinstance(b, Rigid)] or [np.zeros(0, int)])

    def tributary_lengths(self) -> Array:
        """Per node, half the length of its boundary segments in the reference configuration
        (docs/model.md §10; 0 for interior nodes): nodal force / this = traction."""
        out = np.zeros(self.n)
        for b in self.bodies:
            e = b.boundary_edges() + self.offset[b.name]
            half = 0.5 * np.linalg.norm(self.X[e[:, 1]] - self.X[e[:, 0]], axis=1)
            np.add.at(out, e[:, 0], half)
            np.add.at(out, e[:, 1], half)
        return out

    def penalty_stiffness_bound(self) -> float:
        """An upper bound of the contact tangent's largest eigenvalue (a slave node and its
        master nodes, the penalty times the largest tributary length, twice for the curvature)."""
        return 4.0 * float(self.scene["options"]["penalty"]) * float(self.tributary_lengths().max())


@dataclass
class Loads:
    """Prescribed dofs (`fixed`, held at `values`) and external nodal forces `f` (2N)."""

    fixed: IntArray
    values: Array
    f: Array

    @staticmethod
    def make(model: Model, prescribed: Dict[int, float], f: Optional[Array] = None) -> "Loads":
        dofs = np.array(sorted(prescribed), dtype=np.int64)
        return Loads(dofs, np.array([prescribed[int(d)] for d in dofs]), np.zeros(2 * model.n) if f is None else f)


# ------------------------------------------------------------------ contact


@dataclass
class ContactState:
    f: Array                              # contact forces, 2N
    energy: float
    K: Optional[sp.csr_matrix]            # contact tangent, 2N x 2N
    pressure: Optional[Array]             # docs/model.md (21), N
    contacts: int
    # friction (docs/model.md §14): the step's dissipation (27) and the stick and slip counts
    dissipation: float = 0.0
    sticking: int = 0
    slipping: int = 0
    result: Optional[Any] = None          # the client's Result, when the contacts were asked for


class Contact:
    """The contact at a displacement u, through a binary session (one step per call).

    With friction (docs/model.md §14) every call is a trial from the session's committed
    history, and `commit` makes its anchors the committed ones (the default, as a
    frictionless scene does not care); `contacts` asks for the contacts (their stick or
    slip state), which makes the answer JSON."""

    def __init__(self, session: Any, X: Array) -> None:
        self.session, self.X, self.calls = session, X, 0

    def __call__(self, u: Array, stiffness: bool = True, pressure: bool = False, commit: bool = True,
                 contacts: bool = False) -> ContactState:
        outputs = (["forces", "energy"] + (["stiffness"] if stiffness else []) + (["pressure"] if pressure else [])
                   + (["contacts"] if contacts else []))
        res = self.session.contact(self.X + u.reshape(-1, 2), outputs=outputs, commit=commit)
        self.calls += 1
        sm = res.summary
        return ContactState(res.force_array().ravel().copy(), float(res.energy),
                            res.stiffness.tocsr() if stiffness else None,
                            res.pressure_array().copy() if pressure else None, int(sm.contacts),
                            float(sm.dissipation), int(sm.sticking), int(sm.slipping), res if contacts else None)


# ------------------------------------------------------------------ solvers


@dataclass
class Solve:
    u: Array
    state: ContactState
    iterations: int
    calls: int
    history: List[float]
    converged: bool
    energy: float = 0.0       # Pi at u

    def reaction(self, model: Model, loads: Loads) -> Array:
        """The force the supports apply, at every dof (0 on free dofs)."""
        r = model.K @ self.u - loads.f - self.state.f
        out = np.zeros_like(r)
        out[loads.fixed] = r[loads.fixed]
        return out


def _start(loads: Loads, u0: Array) -> Array:
    u = u0.copy()
    u[loads.fixed] = loads.values
    return u


def _energy(model: Model, loads: Loads, u: Array, contact_energy: float) -> float:
    return 0.5 * float(u @ (model.K @ u)) - float(loads.f @ u) + contact_energy


def _gradient(model: Model, loads: Loads, u: Array, st: ContactState) -> Array:
    g = model.K @ u - loads.f - st.f
    g[loads.fixed] = 0.0
    return g


def newton(model: Model, contact: Contact, loads: Loads, u0: Array, tol: float, max_iter: int = 60,
           pressure: bool = False) -> Solve:
    """Newton's method on Pi with the contact's consistent tangent; backtracking (Armijo) on
    Pi, a step that lowers the residual also accepted (near the solution Pi's change drowns in
    its round-off). Converged when the largest free residual force is below `tol`."""
    calls0 = contact.calls
    free = np.setdiff1d(np.arange(2 * model.n), loads.fixed)
    Kff = model.K[free][:, free]
    u = _start(loads, u0)
    st = contact(u, pressure=pressure)
    history: List[float] = []
    for it in range(max_iter + 1):
        g = _gradient(model, loads, u, st)
        norm = float(np.abs(g).max())
        history.append(norm)
        if norm < tol or it == max_iter:
            break
        assert st.K is not None
        J = (Kff + st.K[free][:, free]).tocsc()
        du = np.zeros_like(u)
        du[free] = spla.spsolve(J, -g[free])
        pi0, slope, t = _energy(model, loads, u, st.energy), float(g @ du), 1.0
        while True:
            trial_u = u + t * du
            trial = contact(trial_u, pressure=pressure)
            gt = _gradient(model, loads, trial_u, trial)
            if (_energy(model, loads, trial_u, trial.energy) <= pi0 + 1e-4 * t * slope
                    or float(np.abs(gt).max()) < (1 - 1e-4 * t) * norm or t < 1e-8):
                break
            t *= 0.5
        u, st = trial_u, trial
    return Solve(u, st, len(history) - 1, contact.calls - calls0, history, history[-1] < tol,
                 _energy(model, loads, u, st.energy))


def fire(model: Model, contact: Contact, loads: Loads, u0: Array, tol: float, max_iter: int = 200000,
         dt: Optional[float] = None) -> Solve:
    """FIRE (Bitzek et al. 2006: N_min 5, f_inc 1.1, f_dec 0.5, alpha_start 0.1, f_alpha 0.99,
    dt_max 10 dt) on Pi with unit masses, from the forces alone. The default time step is 0.1 /
    sqrt(an upper bound of the largest eigenvalue): the elastic stiffness's Gershgorin bound
    plus the penalty's."""
    calls0 = contact.calls
    free = np.setdiff1d(np.arange(2 * model.n), loads.fixed)
    if dt is None:
        Kff = model.K[free][:, free]
        gersh = float(np.abs(Kff).sum(axis=1).max())
        dt = 0.1 / math.sqrt(gersh + model.penalty_stiffness_bound())
    u = _start(loads, u0)
    v = np.zeros_like(u)
    st = contact(u, stiffness=False)
    f = -_gradient(model, loads, u, st)
    dt_max, a, npos, it = 10.0 * dt, 0.1, 0, 0
    history = [float(np.abs(f).max())]
    while history[-1] >= tol and it < max_iter:
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
        st = contact(u, stiffness=False)
        f = -_gradient(model, loads, u, st)
        it += 1
        if it % 100 == 0 or float(np.abs(f).max()) < tol:
            history.append(float(np.abs(f).max()))
    history.append(float(np.abs(f).max()))
    return Solve(u, st, it, contact.calls - calls0, history, history[-1] < tol, _energy(model, loads, u, st.energy))


class Tied:
    """Reduced dofs v with u = T v: each group of nodes moves as one rigid translation (a
    platen bonded to them that can neither turn nor stretch), every other dof is its own.
    `col[d]` is the reduced dof of full dof d (a group's nodes share theirs); the non-tied
    dofs come first, in order, then each group's (x, y)."""

    def __init__(self, model: Model, groups: Sequence[npt.ArrayLike]) -> None:
        n = 2 * model.n
        col = np.full(n, -1, dtype=np.int64)
        tied = np.concatenate([np.asarray(g, dtype=np.int64) for g in groups] or [np.zeros(0, np.int64)])
        own = np.setdiff1d(np.arange(n), np.concatenate([2 * tied, 2 * tied + 1]))
        col[own] = np.arange(len(own))
        self.group_dofs: List[Tuple[int, int]] = []
        for k, g in enumerate(groups):
            g = np.asarray(g, dtype=np.int64)
            x, y = len(own) + 2 * k, len(own) + 2 * k + 1
            col[2 * g], col[2 * g + 1] = x, y
            self.group_dofs.append((x, y))
        self.col = col
        self.m = len(own) + 2 * len(self.group_dofs)
        self.T = sp.csr_matrix((np.ones(n), (np.arange(n), col)), shape=(n, self.m))

    def reduced(self, u: Array) -> Array:
        """v of a u that moves every group rigidly (each reduced dof takes one of its full dofs' values)."""
        v = np.zeros(self.m)
        v[self.col] = u
        return v


@dataclass
class FrictionSolve:
    v: Array                  # the reduced dofs
    u: Array                  # T v
    state: ContactState       # the committed step at u
    reaction: Array           # the force the supports apply on each reduced dof (0 on free ones)
    iterations: int
    calls: int
    history: List[float]
    converged: bool


def newton_friction(model: Model, contact: Contact, tied: Tied, loads: Loads, v0: Array, tol: float,
                    max_iter: int = 60, contacts: bool = False, commit_anyway: bool = False) -> FrictionSolve:
    """One load increment with friction (docs/model.md §14), in the reduced dofs of `tied`
    (`loads` there too: its fixed dofs, values and forces are reduced ones).

    Newton's method on the residual r(v) = T^T (K T v - f_contact(T v)) - f with the contact's
    consistent tangent, which is not symmetric in slip (spsolve takes it as it is). There is no
    energy to minimise (slip dissipates: the problem is path-dependent), so the line search is
    on the residual (`_residual_line_search`). Every iteration is a trial from the session's
    committed history (`commit=False`); at convergence the converged v is evaluated once more
    with `commit=True`, which makes its anchors the history of the next increment (and asks for
    the contacts when `contacts`); without convergence nothing is committed (unless
    `commit_anyway`: the last iterate then). Converged when the largest free residual is below
    `tol`."""
    calls0 = contact.calls
    T = tied.T
    Kr = (T.T @ model.K @ T).tocsr()
    free = np.setdiff1d(np.arange(tied.m), loads.fixed)

    def at(v: Array) -> Tuple[ContactState, Array]:
        st = contact(T @ v, commit=False)
        r = Kr @ v - T.T @ st.f - loads.f
        r[loads.fixed] = 0.0
        return st, r

    v = _start(loads, v0)
    st, r = at(v)
    history: List[float] = []
    for it in range(max_iter + 1):
        norm = float(np.abs(r).max())
        history.append(norm)
        if norm < tol or it == max_iter:
            break
        assert st.K is not None
        J = (Kr + T.T @ st.K @ T).tocsr()[free][:, free].tocsc()
        dv = np.zeros_like(v)
        dv[free] = spla.spsolve(J, -r[free])
        v, st, r = _residual_line_search(at, v, dv, r)
    converged = history[-1] < tol
    if converged or commit_anyway:    # else nothing: the caller may cut the increment back
        st = contact(T @ v, stiffness=False, commit=True, contacts=contacts)
    reaction = Kr @ v - T.T @ st.f - loads.f
    reaction[free] = 0.0
    return FrictionSolve(v, T @ v, st, reaction, len(history) - 1, contact.calls - calls0, history, converged)


def _residual_line_search(at: Any, v: Array, dv: Array, r0: Array) -> Tuple[Array, ContactState, Array]:
    """A step t dv along Newton's direction that lowers the residual's 2-norm (free dofs; r is 0
    on fixed ones): Armijo with Newton's slope -|r|^2, |r(t)|^2 <= (1 - 2e-4 t) |r0|^2.

    The full step first. When it fails, backtracking starts from the root of the residual's
    component along the step, s(t) = dv . r(v + t dv), interpolated between s(0) and s(1)
    when they differ in sign (for a conservative problem, the energy's minimum on the line),
    kept within [1/16, 1/2], then halves. That root is where a full step overshoots because
    contacts not yet in the tangent close (their penalty forces jump in): there halving from
    1 would take several contact calls to get down to it. It is only a starting point: the
    step taken must lower |r| (accepting a rise there let Newton cycle between stick and
    slip states of the same contacts)."""
    n0 = float(r0 @ r0)
    st, r = at(v + dv)
    if float(r @ r) <= (1.0 - 2e-4) * n0:
        return v + dv, st, r
    s0, s1 = float(dv @ r0), float(dv @ r)
    t = min(max(s0 / (s0 - s1), 1.0 / 16.0), 0.5) if s0 < 0.0 < s1 else 0.5
    while True:
        st, r = at(v + t * dv)
        if float(r @ r) <= (1.0 - 2e-4 * t) * n0 or t < 1e-3:
            return v + t * dv, st, r
        t *= 0.5


# ------------------------------------------------------------------ the service


@contextlib.contextmanager
def service(url: Optional[str] = None, build_dir: Optional[Path] = None) -> Iterator[ntscontact.Client]:
    """A client of `url`, or of an ntscontactd started from `build_dir`/bin on a free port
    (stopped, by its own pid, on exit)."""
    proc: Optional[subprocess.Popen[str]] = None
    if url is None:
        exe = (build_dir or REPO / "build") / "bin" / "ntscontactd"
        if not exe.exists():
            raise SystemExit(f"{exe} not found: build it (bash scripts/build.sh) or give --url")
        proc = subprocess.Popen([str(exe), "--port", "0", "--quiet"], stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, text=True)
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 20.0)
        m = re.search(r":(\d+)\s*$", proc.stdout.readline() if ready else "")
        if not m:
            proc.kill()
            proc.wait()
            raise SystemExit("ntscontactd did not report its port")
        url = f"http://127.0.0.1:{m.group(1)}"
    try:
        with ntscontact.Client(url, timeout=300.0) as client:
            yield client
    finally:
        if proc is not None:
            proc.terminate()
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            if proc.stdout is not None:
                proc.stdout.close()


@contextlib.contextmanager
def coupled(client: ntscontact.Client, model: Model) -> Iterator[Contact]:
    """A session of the model's scene: `Contact` at displacements from the reference X."""
    with client.session(model.scene) as s:
        yield Contact(s, model.X)
