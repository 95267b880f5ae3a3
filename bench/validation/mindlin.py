"""Cattaneo-Mindlin in 2D (plane strain cylinders): a normal load P, then a tangential load
Q < mu P, on two equal elastic half-disks, against the analytic partial slip; and the
same on an elastic half-disk on a rigid flat, where it is only approximate.

Theory (Johnson, Contact Mechanics §7.1). Two bodies of the same material have Dundurs'
beta = 0: the normal and tangential problems uncouple. The pressure is Hertz's (hertz.py),
p(x) = p0 sqrt(1 - x^2/a^2); a monotonic Q (no rotation) leaves a central stick zone
|x| < c, c = a sqrt(1 - Q/(mu P)), and the shear traction

    q(x) = mu p0 sqrt(1 - x^2/a^2) - mu p0 (c/a) sqrt(1 - x^2/c^2)   |x| < c
    q(x) = mu p(x)                                                   c <= |x| <= a

(the slip annulus at the Coulomb limit), until Q = mu P slides the whole contact.

The bodies: half-disks of radius R (fem.graded_half_disk), the upper one's flat edge at
y = R, its arc touching the lower one's (its mirror image, flat edge at y = -R) at the
origin; in the "flat" variant a rigid flat (`role: master`, alpha 0) replaces the lower
one. Each half-disk's flat edge is bonded to a rigid platen that translates without
turning (fem.Tied): the lower one held, the upper one loaded. Two-pass contact between
the half-disks (both slaves and masters, alpha 0.2 as in hertz.py's disks), Coulomb
friction mu with the tangential penalty eps_T = eps (docs/model.md §14).

The loading, each increment solved by fem.newton_friction (trial steps, committed at
convergence; an increment Newton fails is cut in two, `cutbacks`), each from the last
solution plus the last increment's change (a predictor):
1. P in `normal_steps` increments, friction on, the platen's x held (a new contact
   sticks with no tangential stiffness, §14: nothing else would hold it);
2. Q = mu P k / q_steps, k = 1 .. q_steps - 1, a force on the free platen x
   (measured at the `ratios` of mu P);
3. the platen's x pushed on by displacement steps until every contact slips (at
   Q = mu P there is no static equilibrium under a force), then `slide_steps` more, and on
   to the first one in which every contact slips (in some, a contact that closed at the
   leading edge still sticks: a contact new in a step carries no tangential force in it,
   §14): there the interface carries mu times its load.

Measured: tractions from the upper body's nodal contact forces over their tributary lengths
(docs/model.md (21)) resolved on the interface's current tangent and normal (`tractions`);
c from the contacts' stick and slip states (`stick_edge`); the platen's Q / (mu P). Why
a/R = 0.025 (hertz.py's §1 runs use 0.1 too): C-M is a small-strain theory, and the
interface tilts under the shear by about (1 - 2 nu)(1 + nu) q / E (each half-disk's surface
moves down on one side and up on the other by as much; beta = 0 keeps the gap, not the
surfaces, from it): at a/R = 0.1 (p0 / E = 0.055) that slope is 0.018 at full sliding, the
platen's Q / (mu P) 0.94 and the interface's own Q / (mu P) 2.5% above the applied one in
partial slip; at 0.025 a quarter of that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from fem import (Array, Contact, Elastic, FrictionSolve, IntArray, Loads, Model, Rigid, Tied, boundary_segments,
                 coupled, graded_half_disk, mirrored, newton_friction)
from hertz import HertzGeometry, load_for, peak


def mindlin_shear(x: Array, a: float, c: float, p0: float, mu: float) -> Array:
    """The Cattaneo-Mindlin shear traction at x (see the module's doc)."""
    q = mu * p0 * np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None))
    return q - np.where(np.abs(x) < c, mu * p0 * (c / a) * np.sqrt(np.clip(1.0 - (x / c) ** 2, 0.0, None)), 0.0)


def stick_half_width(a: float, Q: float, mu: float, P: float) -> float:
    """c = a sqrt(1 - Q / (mu P))."""
    return a * math.sqrt(max(1.0 - Q / (mu * P), 0.0))


@dataclass
class Partial:
    """The contact at one Q < mu P (after the increments up to it)."""

    ratio: float              # Q / (mu P), applied
    c_a: float                # analytic c / a
    c_state: float            # c from the contacts' states, / a (Hertz): see `stick_edge`
    c_lo: float               # the outermost sticking slave's |x| / a and the next slipping one's, the
    c_hi: float               # worse of the two sides (c_lo the smaller, c_hi the larger)
    q_rms: float              # RMS of (q_i - q_CM(x_i)) / (mu p0) over the nodes with |x| < a
    q_max: float              # max |q_i - q_CM(x_i)| / (mu p0) over every node in contact
    q_bulk: float             # the same away from C-M's two singular points: |x| < a - h and ||x| - c| > h
    interface_ratio: float    # sum q_i l_i / (mu sum p_i l_i): the applied Q / (mu P) as the interface carries it
    c_int: float              # C-M's c / a at that ratio
    sticking: int
    slipping: int
    contacts: int
    x: Array = field(default_factory=lambda: np.zeros(0))    # the upper body's nodes in contact, by x
    p: Array = field(default_factory=lambda: np.zeros(0))    # their pressure and shear traction
    q: Array = field(default_factory=lambda: np.zeros(0))
    stick_x: Array = field(default_factory=lambda: np.zeros(0))   # the sticking slaves' x

    @property
    def bracketed(self) -> bool:
        """C-M's c lies between the outermost sticking slave and the next slipping one, on both sides."""
        return self.c_lo <= self.c_a <= self.c_hi

    @property
    def bracketed_int(self) -> bool:
        """The same for C-M's c at the interface's own Q / (mu P)."""
        return self.c_lo <= self.c_int <= self.c_hi


@dataclass
class SlideStep:
    """One displacement step of the sliding phase."""

    shift: float              # the platen's x beyond the last partial-slip step, / a
    ratio: float              # the platen's Q / (mu P)
    interface_ratio: float    # sum q_i l_i / (mu sum p_i l_i), the interface's own frame
    resolved_ratio: float     # the platen's (Q, P) resolved on the interface's mean slope s:
                              # (Q - P s) / (mu (P + Q s))
    sticking: int
    slipping: int
    new_share: float          # the normal force of the contacts with no tangential force (new this step), / all


@dataclass
class MindlinRun(HertzGeometry):
    kind: str                 # "disks" (two equal half-disks, beta = 0) or "flat" (a half-disk on a rigid flat)
    levels: int               # arc bisections: h = 2 R sin(pi / (3 2^(levels + 1)))
    a_R: float = 0.025        # target a / R (P from Hertz): small, C-M is a small-strain theory (see solve)
    eps_ratio: float = 1e3    # penalty * a / E* (eps_T the same)
    mu: float = 0.3
    R: float = 1.0
    E: float = 1.0
    nu: float = 0.3
    alpha: float = 0.2        # the half-disks' own smoothing (the flat's is 0)
    normal_steps: int = 5
    q_steps: int = 10         # Q in steps of mu P / q_steps up to (q_steps - 1) mu P / q_steps
    ratios: Tuple[float, ...] = (0.3, 0.6, 0.9)
    slide_steps: int = 3      # displacement steps after every contact slips, before the final small one
    zone: float = 1.3         # the mesh's fine zone, as in hertz.py
    depth: float = 0.5
    grading: float = 6.0      # hertz.py's 12 costs 2.4 times the nodes for 0.1% of mu p0 in q (a/h = 12)
    # results
    nodes: int = 0
    h: float = 0.0
    P: float = 0.0
    a: float = 0.0            # Hertz
    p0: float = 0.0
    a_fem: float = 0.0        # from the nodal pressures' second moment (hertz.py), at Q = 0
    p0_fem: float = 0.0
    Q_normal: float = 0.0     # the platen's x reaction after the normal load, over mu P (0 by symmetry)
    stick_normal: int = 0     # sticking and slipping contacts then
    slip_normal: int = 0
    partial: Dict[float, Partial] = field(default_factory=dict)
    path: List[Tuple[float, float, int, int]] = field(default_factory=list)  # (Q/(mu P), platen x / a, stick, slip)
    slide: List[SlideStep] = field(default_factory=list)
    slide_shift: float = 0.0  # the platen's x beyond the last partial-slip step when every contact first slipped, / a
    final: Optional[SlideStep] = None   # the first sliding step from `slide_steps` after that with every contact slipping
    tilt: float = 0.0         # the interface's slope then (least squares through the upper nodes in contact)
    dissipation: float = 0.0  # summed over the committed steps (eq. (27))
    dissipation_min: float = 0.0   # the smallest step's
    work: float = 0.0         # the platen's work (trapezoids over the increments)
    stored: float = 0.0       # then the elastic energy 1/2 u.K u and the contact's (its springs, normal and
    springs: float = 0.0      # tangential): work = stored + springs + dissipation, to the trapezoids' error
    iterations: List[int] = field(default_factory=list)
    cutbacks: int = 0         # increments Newton failed and that were cut in two
    unconverged: int = 0      # increments committed without convergence (cut in two 3 times deep)
    calls: int = 0
    converged: bool = True

    @property
    def eps(self) -> float:
        return self.eps_ratio * self.E_star / (self.a_R * self.R)


def build(run: MindlinRun) -> Tuple[Model, Tied, List[int], List[int]]:
    """The model, its platen (Tied: the upper body's flat edge), the platen's reduced (x, y)
    dofs and the held reduced dofs (the lower body's flat edge, or the rigid flat)."""
    R, a = run.R, run.a_R * run.R
    mesh = graded_half_disk(R, run.levels, zone=run.zone * a, depth=run.depth * a, grading=run.grading,
                            centre=(0.0, R))
    upper = Elastic("upper", mesh, run.E, run.nu, {"alpha": run.alpha})
    if run.kind == "flat":
        lower: Any = Rigid("flat", np.array([[-2 * R, -R], [2 * R, -R], [2 * R, 0.0], [-2 * R, 0.0]]))
    else:
        lower = Elastic("lower", mirrored(mesh), run.E, run.nu, {"alpha": run.alpha})
    # Friction on every pair: mu, and eps_T = eps (the option's default, stated).
    friction = {"friction": {"coefficient": run.mu, "tangential_penalty": run.eps}} if run.mu > 0 else {}
    model = Model([upper, lower], penalty=run.eps, options=friction)
    X = model.X
    up = model.nodes("upper")
    top = up[np.abs(X[up, 1] - R) < 1e-12 * R]
    tied = Tied(model, [top])
    if run.kind == "flat":
        held_full = model.rigid_dofs()
    else:
        lo = model.nodes("lower")
        bottom = lo[np.abs(X[lo, 1] + R) < 1e-12 * R]
        held_full = np.concatenate([2 * bottom, 2 * bottom + 1])
    held = sorted({int(tied.col[d]) for d in held_full})
    return model, tied, list(tied.group_dofs[0]), held


@dataclass
class Tractions:
    """The upper body's nodes in contact (by reference x) and their tractions in the
    interface's own frame."""

    nodes: IntArray
    x: Array                  # reference x
    p: Array                  # F . n / l
    q: Array                  # -F . tau / l
    l: Array
    slope: float              # least-squares slope of their current positions

    def ratio(self, mu: float) -> float:
        """sum q l / (mu sum p l): 1 when every contact slips."""
        return float(self.q @ self.l) / (mu * float(self.p @ self.l))


def tractions(model: Model, u: Array, f: Array) -> Tractions:
    """The nodal contact force F of each upper node in contact (the whole force: with
    two-pass contact its own slave force and the other body's slaves' reactions on its
    segments, docs/validation.md §1b) over its tributary length l (docs/model.md (21)),
    resolved on the upper surface's current tangent tau there (the chord of its two
    neighbours, +x) and normal n (+y). Why the current frame: the interface tilts under the
    shear (both surfaces move down on one side, up on the other, by as much: beta = 0 keeps
    the gap, not the surfaces, from it), and the contact forces follow it; the global
    x and y would mix a part of p into q."""
    up = model.nodes("upper")
    seg = boundary_segments(model.body("upper").mesh) + up[0]
    nxt = dict(zip(seg[:, 0].tolist(), seg[:, 1].tolist()))
    prv = dict(zip(seg[:, 1].tolist(), seg[:, 0].tolist()))
    x = model.X + u.reshape(-1, 2)
    F = f.reshape(-1, 2)
    on = np.array(sorted(set(nxt) & set(prv)), dtype=np.int64)
    on = on[F[on, 1] > 0.0]
    on = on[np.argsort(model.X[on, 0])]
    t = x[[nxt[int(k)] for k in on]] - x[[prv[int(k)] for k in on]]
    t /= np.linalg.norm(t, axis=1)[:, None]
    n = np.stack([-t[:, 1], t[:, 0]], axis=1)
    l = model.tributary_lengths()[on]
    p = np.einsum("ij,ij->i", F[on], n) / l
    q = -np.einsum("ij,ij->i", F[on], t) / l
    slope = float(np.polyfit(x[on, 0], x[on, 1], 1)[0]) if len(on) > 1 else 0.0
    return Tractions(on, model.X[on, 0], p, q, l, slope)


def stick_edge(xs: Array, stick: Array) -> Tuple[float, float, float]:
    """c from the slaves' states: on each side of x = 0 the outermost sticking slave's |x|
    and the next slipping one's beyond it; returns (c, lo, hi): c the mean of the two sides'
    midpoints, lo the smaller outermost-sticking |x|, hi the larger next-slipping |x|."""
    mids, los, his = [], [], []
    for sign in (-1.0, 1.0):
        d = sign * xs[sign * xs >= 0.0]
        st = stick[sign * xs >= 0.0]
        inner = float(d[st].max()) if st.any() else 0.0
        beyond = d[~st & (d > inner)]
        outer = float(beyond.min()) if beyond.size else inner
        mids.append(0.5 * (inner + outer))
        los.append(inner)
        his.append(outer)
    return 0.5 * (mids[0] + mids[1]), min(los), max(his)


def measure(run: MindlinRun, model: Model, s: FrictionSolve, Q: float) -> Partial:
    """The tractions (`tractions`) and the stick zone against Cattaneo-Mindlin at Q."""
    tr = tractions(model, s.u, s.state.f)
    a, mu, p0 = run.a, run.mu, run.p0
    c = stick_half_width(a, Q, mu, run.P)
    err = (tr.q - mindlin_shear(tr.x, a, c, p0, mu)) / (mu * p0)
    inside = np.abs(tr.x) < a
    res = s.state.result
    assert res is not None
    X = model.X
    sx = np.array([X[model.nodes(k.slave_body, [k.slave_node])[0], 0] for k in res.contacts])
    stick = np.array([k.state == "stick" for k in res.contacts])
    c_state, lo, hi = stick_edge(sx, stick)
    # the profile's error away from its two singular points: q's slope is infinite at |x| = c
    # (the stick correction's square root) and p's at the edge, where a node's traction stands
    # for a tributary length l across the singularity
    bulk = (np.abs(tr.x) < a - run.h) & (np.abs(np.abs(tr.x) - c) > run.h)
    return Partial(Q / (mu * run.P), c / a, c_state / a, lo / a, hi / a,
                   float(np.sqrt(np.mean(err[inside] ** 2))), float(np.abs(err).max()),
                   float(np.abs(err[bulk]).max()), tr.ratio(mu), math.sqrt(max(1.0 - tr.ratio(mu), 0.0)),
                   int(s.state.sticking), int(s.state.slipping), int(s.state.contacts), tr.x, tr.p, tr.q, sx[stick])


def slide_step(run: MindlinRun, model: Model, s: FrictionSolve, shift: float, ux: int) -> SlideStep:
    res = s.state.result
    assert res is not None
    fn = np.array([np.linalg.norm(np.subtract(k.force, k.tangential_force)) for k in res.contacts])
    new = np.array([not any(k.tangential_force) for k in res.contacts])
    tr = tractions(model, s.u, s.state.f)
    Q, P, sl = float(s.reaction[ux]), run.P, tr.slope
    return SlideStep(shift, Q / (run.mu * P), tr.ratio(run.mu), (Q - P * sl) / (run.mu * (P + Q * sl)),
                     int(s.state.sticking), int(s.state.slipping), float(fn[new].sum() / fn.sum()) if fn.size else 0.0)


def solve(client: Any, run: MindlinRun) -> MindlinRun:
    R, a = run.R, run.a_R * run.R
    run.a = a
    run.P = load_for(a, run.R_star, run.E_star)
    run.p0 = peak(run.P, a)
    model, tied, (ux, uy), held = build(run)
    run.nodes = model.n
    X = model.X
    up = model.nodes("upper")
    e = model.body("upper").boundary_edges()
    Xu = X[up]
    mid = 0.5 * (Xu[e[:, 0]] + Xu[e[:, 1]])
    zone = (np.abs(mid[:, 0]) <= a) & (mid[:, 1] < 0.5 * R)
    run.h = float(np.linalg.norm(Xu[e[zone, 1]] - Xu[e[zone, 0]], axis=1).max())
    tol = 1e-10 * run.P
    l = model.tributary_lengths()
    # The first increment starts from the upper body moved down by that increment's
    # geometric interference a1^2 / (2 R*) (hertz.py): nothing holds it before it touches.
    a1 = a * math.sqrt(1.0 / run.normal_steps)
    u = np.zeros(2 * model.n)
    u[2 * up + 1] = -a1 * a1 / (2.0 * run.R_star)
    guess = tied.reduced(u)
    v = np.zeros(tied.m)          # the unloaded state
    dissipations: List[float] = []
    platen = [(np.zeros(2), np.zeros(2))]     # (force, displacement) after each increment, from the unloaded start
    v_prev = np.zeros_like(v)
    total = np.zeros(tied.m)      # the force on each reduced dof after the last increment (applied or reaction)

    def accept(s: FrictionSolve, f: Array) -> None:
        nonlocal v, v_prev, total
        run.iterations.append(s.iterations)
        run.converged = run.converged and s.converged
        run.unconverged += 0 if s.converged else 1
        dissipations.append(s.state.dissipation)
        v, v_prev, total = s.v, v, f + s.reaction
        platen.append((total[[ux, uy]].copy(), v[[ux, uy]].copy()))

    def solve_to(contact: Contact, fixed: Dict[int, float], f: Array, v0: Array, contacts: bool,
                 depth: int = 0) -> FrictionSolve:
        """Newton to these loads (`fixed` values, forces `f` on the other dofs) from v0. When it
        fails (committing nothing), the increment is cut in two halves from the last converged
        state, the first committed (at most 3 deep, where the last iterate is committed and the
        run marked not converged): the loads halfway are the fixed dofs
        halfway from where they are, the forces halfway from the last increment's."""
        keys = sorted(fixed)
        loads = Loads(np.array(keys, dtype=np.int64), np.array([fixed[d] for d in keys]), f)
        s = newton_friction(model, contact, tied, loads, v0, tol, max_iter=30, contacts=contacts,
                            commit_anyway=depth == 3)
        if s.converged or depth == 3:     # (not converged: reported, run.converged)
            return s
        run.cutbacks += 1
        half_f = 0.5 * (total + f)
        half_f[keys] = 0.0
        first = solve_to(contact, {d: 0.5 * (float(v[d]) + x) for d, x in fixed.items()}, half_f, v, False, depth + 1)
        accept(first, half_f)
        return solve_to(contact, fixed, f, v, contacts, depth + 1)

    def step(contact: Contact, fixed: Dict[int, float], fx: float, contacts: bool, fy: float = -run.P,
             extrapolate: float = 1.0, start: Optional[Array] = None) -> FrictionSolve:
        """One increment to these loads, from `start`, else from the last one's solution plus
        `extrapolate` times the last increment's change (a predictor: Newton from the last
        solution alone overshoots where contacts close; 0 where the loading changes its kind)."""
        f = np.zeros(tied.m)
        f[uy], f[ux] = fy, fx
        v0 = start if start is not None else v + extrapolate * (v - v_prev)
        s = solve_to(contact, fixed, f, v0, contacts)
        accept(s, f)
        return s

    base = {d: 0.0 for d in held}
    with coupled(client, model) as contact:
        # 1. the normal load, the platen's x held
        for k in range(1, run.normal_steps + 1):
            s = step(contact, {**base, ux: 0.0}, 0.0, contacts=False, fy=-run.P * k / run.normal_steps,
                     start=guess if k == 1 else None)
        fy = s.state.f.reshape(-1, 2)[up, 1]
        c = up[fy > 0]
        F, x = fy[fy > 0], X[c, 0]
        run.a_fem = 2.0 * math.sqrt(float(F @ x ** 2) / float(F.sum()))
        run.p0_fem = float((F / l[c]).max())
        run.Q_normal = float(s.reaction[ux]) / (run.mu * run.P)
        run.stick_normal, run.slip_normal = s.state.sticking, s.state.slipping
        ux0 = float(v[ux])
        run.path.append((run.Q_normal, 0.0, s.state.sticking, s.state.slipping))
        # 2. Q, a force on the platen's x
        for k in range(1, run.q_steps):
            Q = run.mu * run.P * k / run.q_steps
            want = any(abs(k / run.q_steps - r) < 1e-9 for r in run.ratios)
            s = step(contact, base, Q, contacts=want, extrapolate=0.0 if k == 1 else 1.0)
            run.path.append((k / run.q_steps, (float(v[ux]) - ux0) / a, s.state.sticking, s.state.slipping))
            if want:
                run.partial[round(k / run.q_steps, 9)] = measure(run, model, s, Q)
        # 3. sliding: the platen's x pushed on in steps of a third of the way it went from
        # Q = 0 to the last Q, until every contact slips, then `slide_steps` more, then one of
        # 1e-3 of that (no contact closes in it: a new one carries no tangential force, §14)
        du = (float(v[ux]) - ux0) / 3.0
        last = float(v[ux])
        after = -1                # steps since every contact first slipped
        for k in range(40):
            s = step(contact, {**base, ux: float(v[ux]) + du}, 0.0, contacts=True, extrapolate=0.0 if k == 0 else 1.0)
            st = slide_step(run, model, s, (float(v[ux]) - last) / a, ux)
            run.slide.append(st)
            run.path.append((st.ratio, (float(v[ux]) - ux0) / a, st.sticking, st.slipping))
            if after < 0 and st.sticking == 0:
                run.slide_shift, after = st.shift, 0
            elif after >= 0:
                after += 1
            # measured at the first step from `slide_steps` on in which every contact slips: in
            # some, a contact that closed in it (no tangential force, §14) or in the step before
            # (its spring then stretched by one step only) still sticks
            if after >= run.slide_steps and st.sticking == 0:
                break
        run.final = st
        run.tilt = tractions(model, s.u, s.state.f).slope
        run.calls = contact.calls
    run.dissipation = float(sum(dissipations))
    run.dissipation_min = float(min(dissipations))
    run.work = float(sum(0.5 * (f0 + f1) @ (d1 - d0) for (f0, d0), (f1, d1) in zip(platen, platen[1:])))
    run.stored = 0.5 * float(s.u @ (model.K @ s.u))
    run.springs = float(s.state.energy)
    return run


def summary(run: MindlinRun) -> Dict[str, Any]:
    out: Dict[str, Any] = {k: getattr(run, k) for k in ("kind", "levels", "nodes", "a_h", "eps_ratio", "mu", "a",
                                                         "a_fem", "p0", "p0_fem", "Q_normal", "stick_normal",
                                                         "slip_normal", "slide_shift", "final", "tilt",
                                                         "dissipation", "dissipation_min", "work", "stored", "springs", "iterations", "cutbacks",
                                                         "calls", "converged")}
    out["slide"] = run.slide
    for r, pt in run.partial.items():
        out[f"partial_{r:g}"] = {k: getattr(pt, k) for k in ("c_a", "c_state", "c_lo", "c_hi", "q_rms", "q_max",
                                                             "q_bulk", "interface_ratio", "sticking", "slipping",
                                                             "contacts", "bracketed")}
    return out
