"""Pictures of a scene and a result with matplotlib (``pip install matplotlib``):
the bodies as the contact surface sees them (each corner smoothed by its
body's alpha, docs/model.md §3; a body's segments off its contact surface,
§13, dotted, and the surface's ends sharp) and the contact forces as arrows."""

from __future__ import annotations

from typing import Any, List, Optional

import numpy as np

__all__ = ["smoothed_loop", "surface_runs", "plot"]


def _corners(p: np.ndarray, alpha: float, samples: int, sharp: Optional[np.ndarray]) -> List[np.ndarray]:
    """Each corner of a loop: its corner polynomial from Xa = X3 + alpha (X2 - X3)
    to Xb = X3 + alpha (X4 - X3), or the node itself where ``sharp``."""
    xi = np.linspace(-1.0, 1.0, samples)
    n2, n3, n4 = alpha * (1 - xi) ** 2 / 4, 1 - alpha * (1 + xi ** 2) / 2, alpha * (1 + xi) ** 2 / 4
    prev, nxt = np.roll(p, 1, axis=0), np.roll(p, -1, axis=0)
    return [p[j:j + 1] if alpha <= 0.0 or (sharp is not None and sharp[j]) else
            n2[:, None] * prev[j] + n3[:, None] * p[j] + n4[:, None] * nxt[j] for j in range(len(p))]


def smoothed_loop(points: np.ndarray, alpha: float, samples: int = 8, sharp: Optional[np.ndarray] = None) -> np.ndarray:
    """The closed outline of a loop with every corner replaced by its corner
    polynomial from Xa = X3 + alpha (X2 - X3) to Xb = X3 + alpha (X4 - X3);
    the corners where ``sharp`` (a boolean per node) is true stay sharp."""
    curve = np.vstack(_corners(np.asarray(points, dtype=np.float64), alpha, samples, sharp))
    return np.vstack([curve, curve[:1]])


def surface_runs(points: np.ndarray, alpha: float, on: np.ndarray, samples: int = 8) -> List[np.ndarray]:
    """The pieces of a loop's outline on its body's contact surface (``on``: a
    boolean per segment, from node k to k + 1), as the core sees them: a
    corner inside a piece smoothed, a piece's ends sharp (docs/model.md §13)."""
    p = np.asarray(points, dtype=np.float64)
    m = len(p)
    corners = _corners(p, alpha, samples, ~(on & np.roll(on, 1)))
    runs = []
    for k in np.flatnonzero(on & ~np.roll(on, 1)):  # a piece starts at node k
        path, j = [p[k:k + 1]], int(k)
        while on[j % m]:
            j += 1
            path.append(corners[j % m] if on[j % m] else p[j % m:j % m + 1])
        runs.append(np.vstack(path))
    return runs


def plot(scene: Any, result: Any = None, ax: Any = None, *, positions: Optional[np.ndarray] = None,
         arrows: bool = True, scale: Optional[float] = None) -> Any:
    """Draw ``scene`` (at ``positions``, default its own; or at the positions a
    result of the client remembers) and the forces of ``result``. Returns the axes."""
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("plot needs matplotlib: pip install matplotlib") from exc
    from .vtk import on_surface, surface_loops

    if positions is None and result is not None and getattr(result, "_scene", None) is not None:
        positions = result._positions()
    x = scene.positions() if positions is None else np.asarray(positions, dtype=np.float64)
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    offsets = np.concatenate([[0], np.cumsum([b.node_count for b in scene])]).astype(int)
    default_alpha = scene.alpha if scene.alpha is not None else 0.2
    for k, (body, loops) in enumerate(zip(scene, surface_loops(scene))):
        a = body.alpha if body.alpha is not None else default_alpha
        colour = "0.35" if body.role == "master" else f"C{k % 10}"
        for lp, on in zip(loops, on_surface(body, loops)):
            pts = x[offsets[k] + lp]
            if on.all():
                outline = smoothed_loop(pts, a)
                ax.plot(outline[:, 0], outline[:, 1], "-", color=colour, lw=1.2)
            else:  # off the contact surface: dotted; the surface's pieces drawn over it
                ax.plot(np.r_[pts[:, 0], pts[:1, 0]], np.r_[pts[:, 1], pts[:1, 1]], ":", color=colour, lw=0.8)
                for run in surface_runs(pts, a, on):
                    ax.plot(run[:, 0], run[:, 1], "-", color=colour, lw=1.2)
            ax.plot(pts[:, 0], pts[:, 1], ".", color=colour, ms=2)
    if result is not None and arrows and result.forces:
        f = result.force_array()
        mag = np.hypot(f[:, 0], f[:, 1])
        on = mag > 0
        if on.any():
            extent = float(np.ptp(x, axis=0).max()) or 1.0
            s = scale if scale is not None else 0.08 * extent / float(mag.max())
            ax.quiver(x[on, 0], x[on, 1], s * f[on, 0], s * f[on, 1], angles="xy", scale_units="xy", scale=1.0,
                      color="crimson", width=0.003)
    ax.set_aspect("equal")
    return ax
