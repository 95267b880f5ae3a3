#!/usr/bin/env python3
"""Deformable polygons compressed in a periodic box and relaxed with FIRE.

The job ntscontact exists for: a solver (here a few dozen lines of numpy) that owns
the bodies' own mechanics and asks the service for the contact forces at every
step. Each cell is a closed polygon with

* an area spring        ``ka/2 (A - A0)^2``        (the cell's pressure), and
* perimeter springs     ``kl/2 sum_i (l_i - l0)^2`` (one per edge),

as in deformable-polygon models of cells and foams (Boromand et al., PRL 121,
248003, 2018). ``A0`` is a little above the area of the regular polygon of edge
``l0`` (``--inflation``), so a free cell is a taut regular polygon with no soft
mode. The cells (bidisperse, 1 : 1.4) start apart in a periodic box, which is
compressed affinely in ``--stages`` equal steps of packing fraction to ``--phi``
(sum of preferred areas over box area); after each step FIRE relaxes the
packing (loosely between steps, to ``--tol`` at the end). Contact is the
service's penalty node-to-segment contact (``1/2 eps g^2`` per active slave
node, both ways), evaluated with smoothing ``alpha = 0`` (plain NTS) and
``alpha > 0`` (Hermite-smoothed corners).

FIRE (Bitzek, Koskinen, Gähler, Moseler, Gumbsch, PRL 97, 170201, 2006) with its
standard parameters: N_min = 5, f_inc = 1.1, f_dec = 0.5, alpha_start = 0.1,
f_alpha = 0.99, dt_max = 10 dt_0, unit masses, semi-implicit Euler MD steps.
The residual is the largest nodal force norm, max_i |F_i|.

Usage::

    python examples/fire_packing.py                     # starts build/bin/ntscontactd itself
    python examples/fire_packing.py --url http://127.0.0.1:8080 --png packing.png
    python examples/fire_packing.py --tiny --json out.json   # seconds; what the tests run
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
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

try:
    import ntscontact
except ImportError:  # running from a checkout without `pip install -e clients/python`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "clients" / "python" / "src"))
    import ntscontact

REPO = Path(__file__).resolve().parents[1]

# FIRE's standard parameters (Bitzek et al. 2006).
FIRE_NMIN = 5
FIRE_FINC = 1.1
FIRE_FDEC = 0.5
FIRE_ALPHA_START = 0.1
FIRE_FALPHA = 0.99
FIRE_DTMAX_FACTOR = 10.0


@dataclass
class Config:
    cells: int = 8
    vertices: int = 16
    phi: float = 1.02
    phi0: float = 0.55
    stages: int = 20
    penalty: float = 10.0
    ka: float = 1.0
    kl: float = 5.0
    inflation: float = 0.05
    search_radius: float = 0.3
    alphas: Tuple[float, ...] = (0.0, 0.25)
    tol: float = 1e-10
    stage_tol: float = 1e-3
    max_iter: int = 20000
    dt0: float = 0.0  # 0: 0.1 / sqrt(2 penalty + 4 kl), well inside the MD stability limit
    seed: int = 7


# ---------------------------------------------------------------- mechanics


@dataclass
class Packing:
    """Cells as unwrapped (m, 2) polygons (counter-clockwise) in a periodic box of side L."""

    nodes: List[np.ndarray]
    l0: np.ndarray
    a0: np.ndarray
    box: float

    @property
    def counts(self) -> List[int]:
        return [x.shape[0] for x in self.nodes]

    def flat(self) -> np.ndarray:
        return np.concatenate(self.nodes, axis=0)

    def unflat(self, x: np.ndarray) -> List[np.ndarray]:
        out, k = [], 0
        for n in self.counts:
            out.append(x[k:k + n])
            k += n
        return out


def polygon_area(p: np.ndarray) -> float:
    q = np.roll(p, -1, axis=0)
    return 0.5 * float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]))


def shape_energy_forces(p: np.ndarray, l0: float, a0: float, ka: float, kl: float) -> Tuple[float, np.ndarray]:
    """Energy and forces (-gradient) of the area and perimeter springs of one cell."""
    nxt, prv = np.roll(p, -1, axis=0), np.roll(p, 1, axis=0)
    c = p.mean(axis=0)  # shoelace relative to the centroid, for precision
    q, qn = p - c, nxt - c
    area = 0.5 * float(np.sum(q[:, 0] * qn[:, 1] - qn[:, 0] * q[:, 1]))
    d_area = 0.5 * np.stack([nxt[:, 1] - prv[:, 1], prv[:, 0] - nxt[:, 0]], axis=1)
    e = nxt - p
    length = np.hypot(e[:, 0], e[:, 1])
    stretch = length - l0
    energy = 0.5 * ka * (area - a0) ** 2 + 0.5 * kl * float(np.sum(stretch ** 2))
    grad = ka * (area - a0) * d_area
    te = (kl * stretch / length)[:, None] * e  # dU/d(end) of each edge
    grad += np.roll(te, 1, axis=0) - te
    return energy, -grad


def make_packing(cfg: Config) -> Packing:
    rng = np.random.default_rng(cfg.seed)
    m = cfg.vertices
    radii = np.where(np.arange(cfg.cells) % 2 == 0, 1.0, 1.4)
    rng.shuffle(radii)
    l0 = 2.0 * radii * math.sin(math.pi / m)
    a_regular = m * l0 ** 2 / (4.0 * math.tan(math.pi / m))
    a0 = (1.0 + cfg.inflation) * a_regular
    nx = int(math.ceil(math.sqrt(cfg.cells)))
    ny = int(math.ceil(cfg.cells / nx))
    spacing = 2.0 * radii.max() * (1.0 + cfg.inflation) + 0.2
    box = max(math.sqrt(float(a0.sum()) / cfg.phi0), spacing * max(nx, ny))
    cells: List[np.ndarray] = []
    theta = 2.0 * math.pi * np.arange(m) / m
    for i in range(cfg.cells):
        gx, gy = i % nx, i // nx
        centre = np.array([(gx + 0.5) * box / nx, (gy + 0.5) * box / ny])
        slack = box / max(nx, ny) - spacing
        centre += rng.uniform(-0.5, 0.5, size=2) * max(slack, 0.0)
        phase = rng.uniform(0.0, 2.0 * math.pi)
        r = radii[i] * math.sqrt(1.0 + cfg.inflation)
        cells.append(centre + r * np.stack([np.cos(theta + phase), np.sin(theta + phase)], axis=1))
    return Packing(nodes=cells, l0=l0, a0=a0, box=box)


def compress(pk: Packing, new_box: float) -> None:
    """Affine compression of the cell centres (each cell keeps its shape)."""
    s = new_box / pk.box
    for i, p in enumerate(pk.nodes):
        c = p.mean(axis=0)
        wrapped = c - pk.box * np.floor(c / pk.box)
        pk.nodes[i] = p + (wrapped - c) + (s - 1.0) * wrapped
    pk.box = new_box


class Forces:
    """Total forces: the cells' own springs (here) plus contact (the service).

    The contact scene lives in the service as a session: each FIRE step sends
    the positions as raw float64 and gets the forces back the same way. The
    periodic box belongs to the scene, so each compression stage (a new box)
    opens a new session."""

    def __init__(self, client: ntscontact.Client, pk: Packing, cfg: Config, alpha: float) -> None:
        self.client, self.pk, self.cfg = client, pk, cfg
        self.scene = ntscontact.Scene(penalty=cfg.penalty, alpha=alpha, search_radius=cfg.search_radius,
                                      periodic=(pk.box, pk.box), outputs=["forces", "energy"])
        for i, p in enumerate(pk.nodes):
            self.scene.add_body(p, id=f"cell-{i}")
        self.session: Optional[ntscontact.Session] = None
        self.box = math.nan
        self.calls = 0
        self.last: Optional[ntscontact.Result] = None

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None

    def __call__(self, x: np.ndarray, outputs: Optional[Sequence[str]] = None) -> Tuple[float, np.ndarray]:
        pk = self.pk
        parts = pk.unflat(x)
        if self.session is None or self.box != pk.box:
            self.close()
            self.scene.periodic = (pk.box, pk.box)
            for i, p in enumerate(parts):
                self.scene.set_nodes(f"cell-{i}", p)
            self.session = self.client.session(self.scene)
            self.box = pk.box
        res = self.session.contact(x, outputs=outputs)  # x: every node, cells in order
        self.calls += 1
        self.last = res
        energy = res.energy
        forces = res.force_array().copy()
        k = 0
        for i, p in enumerate(parts):
            e, f = shape_energy_forces(p, pk.l0[i], pk.a0[i], self.cfg.ka, self.cfg.kl)
            energy += e
            forces[k:k + len(p)] += f
            k += len(p)
        return energy, forces


@dataclass
class FireStats:
    iterations: int
    residual: float
    converged: bool
    energy: float


ForceFn = Callable[[np.ndarray], Tuple[float, np.ndarray]]


def fire(force: ForceFn, x: np.ndarray, tol: float, max_iter: int, dt0: float) -> Tuple[np.ndarray, FireStats]:
    """FIRE minimisation (Bitzek et al. 2006) from x with zero velocity."""
    v = np.zeros_like(x)
    energy, f = force(x)
    dt, dt_max, a, npos = dt0, FIRE_DTMAX_FACTOR * dt0, FIRE_ALPHA_START, 0
    it = 0
    residual = float(np.max(np.hypot(f[:, 0], f[:, 1])))
    while residual >= tol and it < max_iter:
        p = float(np.vdot(f, v))
        if p > 0.0:
            vn, fn = float(np.linalg.norm(v)), float(np.linalg.norm(f))
            v = (1.0 - a) * v + a * (vn / fn) * f
            if npos > FIRE_NMIN:
                dt = min(dt * FIRE_FINC, dt_max)
                a *= FIRE_FALPHA
            npos += 1
        else:
            v[:] = 0.0
            dt *= FIRE_FDEC
            a = FIRE_ALPHA_START
            npos = 0
        v += dt * f  # unit masses
        x = x + dt * v
        energy, f = force(x)
        residual = float(np.max(np.hypot(f[:, 0], f[:, 1])))
        it += 1
    return x, FireStats(iterations=it, residual=residual, converged=residual < tol, energy=energy)


@dataclass
class Run:
    alpha: float
    seed: int
    iterations: int
    iterations_total: int
    residual: float
    converged: bool
    energy: float
    contact_energy: float
    contacts: int
    touching_pairs: int
    max_penetration: float
    box: float
    seconds: float
    stages: List[Dict[str, Any]] = field(default_factory=list)


def relax(client: ntscontact.Client, cfg: Config, alpha: float) -> Tuple[Run, Packing, ntscontact.Result]:
    t0 = time.perf_counter()
    pk = make_packing(cfg)
    force = Forces(client, pk, cfg, alpha)
    # equal steps in packing fraction, from the loose start to the target
    phi_start = float(pk.a0.sum()) / pk.box ** 2
    boxes = [math.sqrt(float(pk.a0.sum()) / phi) for phi in np.linspace(phi_start, cfg.phi, cfg.stages + 1)[1:]]
    dt0 = cfg.dt0 or 0.1 / math.sqrt(2.0 * cfg.penalty + 4.0 * cfg.kl)
    total = 0
    stages: List[Dict[str, Any]] = []
    stats = FireStats(0, math.inf, False, math.nan)
    for k, box in enumerate(boxes):
        compress(pk, float(box))
        last = k == len(boxes) - 1
        tol = cfg.tol if last else cfg.stage_tol
        x, stats = fire(force, pk.flat(), tol, cfg.max_iter, dt0)
        pk.nodes = [p.copy() for p in pk.unflat(x)]
        total += stats.iterations
        stages.append({"box": float(box), "tol": tol, **asdict(stats)})
    final = force(pk.flat(), outputs=["forces", "energy", "virial", "contacts"])[0]
    force.close()
    res = force.last
    assert res is not None
    pairs = {tuple(sorted((str(c.slave_body), str(c.master_body)))) for c in res.contacts}
    run = Run(alpha=alpha, seed=cfg.seed, iterations=stats.iterations, iterations_total=total, residual=stats.residual,
              converged=stats.converged, energy=final, contact_energy=res.energy, contacts=res.summary.contacts,
              touching_pairs=len(pairs), max_penetration=res.summary.max_penetration, box=pk.box,
              seconds=time.perf_counter() - t0, stages=stages)
    return run, pk, res


# ---------------------------------------------------------------- output


def table(runs: Sequence[Run], cfg: Config) -> str:
    lines = [
        f"{cfg.cells} cells x {cfg.vertices} vertices, phi = {cfg.phi}, penalty = {cfg.penalty}, "
        f"{cfg.stages} compression stages, FIRE to max|F| < {cfg.tol:g} (cap {cfg.max_iter})",
        f"{'alpha':>6} {'FIRE iter':>10} {'all stages':>10} {'residual':>10} {'converged':>9} "
        f"{'energy':>22} {'contacts':>8} {'pairs':>5} {'max pen.':>9} {'s':>6} {'seed':>5}",
    ]
    for r in runs:
        lines.append(f"{r.alpha:6.2f} {r.iterations:10d} {r.iterations_total:10d} {r.residual:10.2e} "
                     f"{'yes' if r.converged else 'no':>9} {r.energy:22.15e} {r.contacts:8d} {r.touching_pairs:5d} "
                     f"{r.max_penetration:9.2e} {r.seconds:6.1f} {r.seed:5d}")
    seeds = sorted({r.seed for r in runs})
    if len(seeds) > 1:
        lines.append(f"mean over {len(seeds)} seeds (FIRE iterations of the last step; converged runs / runs):")
        for alpha in sorted({r.alpha for r in runs}):
            rs = [r for r in runs if r.alpha == alpha]
            it = np.array([r.iterations for r in rs], dtype=float)
            lines.append(f"{alpha:6.2f} {it.mean():10.0f} {np.mean([r.iterations_total for r in rs]):10.0f} "
                         f"{'-':>10} {f'{sum(r.converged for r in rs)}/{len(rs)}':>9} "
                         f"{np.mean([r.energy for r in rs]):22.15e} {np.mean([r.contacts for r in rs]):8.1f} "
                         f"   median iterations {np.median(it):.0f}")
    return "\n".join(lines)


def smoothed_outline(p: np.ndarray, alpha: float, samples: int = 9) -> np.ndarray:
    """The contact surface the service sees: each corner j replaced by its
    polynomial X(xi) = N2 X2 + N3 X3 + N4 X4, xi in [-1, 1] (docs/model.md §4.3, eq. (7));
    the polygon itself when alpha = 0."""
    if alpha <= 0.0:
        return p
    xi = np.linspace(-1.0, 1.0, samples)[:, None]
    n2, n3, n4 = alpha * (1 - xi) ** 2 / 4, 1 - alpha * (1 + xi ** 2) / 2, alpha * (1 + xi) ** 2 / 4
    prv, nxt = np.roll(p, 1, axis=0), np.roll(p, -1, axis=0)
    return np.concatenate([n2 * prv[j] + n3 * p[j] + n4 * nxt[j] for j in range(len(p))], axis=0)


def plot(path: str, results: Sequence[Tuple[Run, Packing, ntscontact.Result]]) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.patches import Polygon
    except ImportError:
        print("matplotlib is not installed: no plot", file=sys.stderr)
        return False
    fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results), 5.5), squeeze=False)
    for ax, (run, pk, res) in zip(axes[0], results):
        L = pk.box
        fmax = max((math.hypot(*c.force) for c in res.contacts), default=1.0) or 1.0
        for i, raw in enumerate(pk.nodes):
            p = smoothed_outline(raw, run.alpha)
            c = p.mean(axis=0)
            shift = L * np.floor(c / L)
            for dx in (-L, 0.0, L):
                for dy in (-L, 0.0, L):
                    q = p - shift + np.array([dx, dy])
                    if q[:, 0].max() < 0 or q[:, 0].min() > L or q[:, 1].max() < 0 or q[:, 1].min() > L:
                        continue
                    ax.add_patch(Polygon(q, closed=True, facecolor=f"C{i % 10}", alpha=0.35, edgecolor="k", lw=0.6))
        for ct in res.contacts:
            i = int(str(ct.slave_body).split("-")[1])
            xs = pk.nodes[i][ct.slave_node]
            xs = xs - L * np.floor(xs / L)
            f = np.array(ct.force) / fmax * 0.12 * L / math.sqrt(len(pk.nodes))
            ax.arrow(xs[0], xs[1], f[0], f[1], width=0.002 * L, head_width=0.008 * L, color="crimson",
                     length_includes_head=True)
        ax.set_xlim(0, L)
        ax.set_ylim(0, L)
        ax.set_aspect("equal")
        ax.set_title(f"alpha = {run.alpha:g}: {run.iterations} FIRE iterations, {run.contacts} contacts",
                     fontsize=10)
    fig.suptitle("cells drawn as the contact surface (corners smoothed when alpha > 0); "
                 "contact forces on the slave nodes (arrows, scaled to the largest)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return True


# ---------------------------------------------------------------- the service


def start_daemon(build_dir: Path, timeout: float = 10.0) -> Tuple[subprocess.Popen, str]:
    """Start ntscontactd on a free loopback port; returns the process and its URL."""
    exe = build_dir / "bin" / "ntscontactd"
    if not exe.exists():
        raise SystemExit(f"{exe} not found: build it (bash scripts/build.sh) or give --url")
    proc = subprocess.Popen([str(exe), "--host", "127.0.0.1", "--port", "0", "--quiet"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    assert proc.stdout is not None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.2)
        if ready:
            line = proc.stdout.readline()
            m = re.search(r":(\d+)\s*$", line)
            if m:
                return proc, f"http://127.0.0.1:{m.group(1)}"
            if not line:
                break
        if proc.poll() is not None:
            break
    proc.kill()
    raise SystemExit("ntscontactd did not report its port")


def parse_args(argv: Optional[Sequence[str]] = None) -> Tuple[argparse.Namespace, Config]:
    d = Config()
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--url", help="a running ntscontactd (default: start one from the build dir)")
    p.add_argument("--build-dir", default=os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))
    p.add_argument("--tiny", action="store_true", help="4 cells x 8 vertices, 8 stages: seconds, for the tests")
    p.add_argument("--cells", type=int)
    p.add_argument("--vertices", type=int)
    p.add_argument("--phi", type=float, default=d.phi, help="final packing fraction sum(A0)/box area")
    p.add_argument("--stages", type=int)
    p.add_argument("--penalty", type=float, default=d.penalty, help="contact penalty eps")
    p.add_argument("--ka", type=float, default=d.ka, help="area spring")
    p.add_argument("--kl", type=float, default=d.kl, help="edge (perimeter) springs")
    p.add_argument("--search-radius", type=float, default=d.search_radius)
    p.add_argument("--alphas", default=",".join(str(a) for a in d.alphas), help="comma-separated, e.g. 0,0.25")
    p.add_argument("--tol", type=float, default=d.tol)
    p.add_argument("--max-iter", type=int, default=d.max_iter)
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--seeds", type=int, default=1, help="run seeds SEED .. SEED+N-1 and print the means")
    p.add_argument("--png", help="plot the final packings with their contact forces (needs matplotlib)")
    p.add_argument("--json", help="write the runs as JSON")
    args = p.parse_args(argv)
    cfg = Config(phi=args.phi, penalty=args.penalty, ka=args.ka, kl=args.kl, search_radius=args.search_radius,
                 tol=args.tol, max_iter=args.max_iter, seed=args.seed,
                 alphas=tuple(float(a) for a in args.alphas.split(",") if a.strip()))
    if args.tiny:
        cfg.cells, cfg.vertices, cfg.stages = 4, 8, 8
    for name in ("cells", "vertices", "stages"):
        if getattr(args, name) is not None:
            setattr(cfg, name, getattr(args, name))
    return args, cfg


def main(argv: Optional[Sequence[str]] = None) -> int:
    args, cfg = parse_args(argv)
    proc = None
    url = args.url
    if url is None:
        proc, url = start_daemon(Path(args.build_dir))
    try:
        results = []
        with ntscontact.Client(url, timeout=60.0) as client:
            for seed in range(args.seed, args.seed + max(1, args.seeds)):
                for alpha in cfg.alphas:
                    results.append(relax(client, replace(cfg, seed=seed), alpha))
        runs = [r for r, _, _ in results]
        print(table(runs, cfg))
        if args.json:
            with open(args.json, "w", encoding="utf-8") as fh:
                json.dump({"config": asdict(cfg), "runs": [asdict(r) for r in runs]}, fh, indent=2)
        if args.png and plot(args.png, results[:len(cfg.alphas)]):
            print(f"wrote {args.png}")
    finally:
        if proc is not None:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
    return 0


if __name__ == "__main__":
    sys.exit(main())
