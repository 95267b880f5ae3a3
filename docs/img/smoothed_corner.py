#!/usr/bin/env python3
"""Draw docs/img/smoothed_corner.png: a corner of a master body, its segments,
the corner polynomial between Xa and Xb (docs/model.md §3), a slave node and
its closest point with the normal. Needs matplotlib."""
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

OUT = pathlib.Path(__file__).with_suffix(".png")
X2, X3, X4, alpha = np.array([-1.0, 0.55]), np.array([0.0, 0.0]), np.array([1.2, 0.35]), 0.35
a, c = X2 - X3, X4 - X3
A = C = alpha * (a + c) / 4
B = alpha * (c - a) / 2
xi = np.linspace(-1, 1, 200)
curve = X3 + np.outer(xi ** 2, A) + np.outer(xi, B) + C
Xa, Xb = X3 + alpha * a, X3 + alpha * c
xs = np.array([0.12, 0.38])
# closest point on the curve, by brute force over a fine sampling
k = int(np.argmin(((curve - xs) ** 2).sum(axis=1)))
tau = 2 * A * xi[k] + B
n = np.array([tau[1], -tau[0]]) / np.hypot(*tau)
fig, ax = plt.subplots(figsize=(6, 3.6))
ax.fill([X2[0], X3[0], X4[0], X4[0], X2[0]], [X2[1], X3[1], X4[1], 1.0, 1.0], color="0.92", zorder=0)
ax.plot([X2[0], X3[0], X4[0]], [X2[1], X3[1], X4[1]], "k--", lw=1, label="segments (alpha = 0)")
ax.plot([X2[0], Xa[0]], [X2[1], Xa[1]], "k-", lw=2)
ax.plot([Xb[0], X4[0]], [Xb[1], X4[1]], "k-", lw=2)
ax.plot(curve[:, 0], curve[:, 1], "C0-", lw=2.5, label=f"corner polynomial, alpha = {alpha}")
for p, name, off in ((X2, "X2", (-0.1, 0.04)), (X3, "X3", (0.03, 0.05)), (X4, "X4", (0.03, 0.03)),
                     (Xa, "Xa", (-0.12, -0.1)), (Xb, "Xb", (0.02, -0.12))):
    ax.plot(*p, "ko", ms=4)
    ax.annotate(name, p + np.array(off))
ax.plot(*xs, "C3o", ms=6)
ax.annotate("slave Xs (inside)", xs + np.array([0.05, 0.03]), color="C3")
ax.plot(*curve[k], "C3x", ms=8)
ax.annotate("", xy=curve[k], xytext=xs, arrowprops=dict(arrowstyle="-", color="C3", ls=":"))
ax.annotate("", xy=curve[k] + 0.3 * n, xytext=curve[k], arrowprops=dict(arrowstyle="->", color="C2"))
ax.annotate("n (outward)", curve[k] + 0.3 * n + np.array([0.02, 0.0]), color="C2")
ax.text(-0.95, 0.85, "master body (interior)", color="0.4")
ax.set_aspect("equal")
ax.set_xlim(-1.1, 1.3)
ax.set_ylim(-0.6, 1.0)
ax.legend(loc="lower left", fontsize=8)
ax.set_title("A smoothed corner: gap g = (Xs - X(xi)) . n < 0 (penetration)", fontsize=10)
fig.tight_layout()
fig.savefig(OUT, dpi=110)
print(OUT)
