"""docs/img/distributed_slabs.png: the decomposition of docs/distributed.md,
computed as mpi/src/slabs.c and halo.c compute it, for a packing of 12 x 12
disks on 3 ranks whose host owns them by bands of columns: the slabs (cuts
at the quantiles of the surface nodes along x, which follows the host: the
longer axis, and its direction leaves the most nodes on their owners'
ranks), and the bodies slab 1 holds (those whose box, grown by the halo,
overlaps it).
usage: python bench/mpi/figure.py docs/img/distributed_slabs.png"""
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

if len(sys.argv) > 2 or (len(sys.argv) == 2 and sys.argv[1].startswith("-")):  # (not a file to write over)
    print(__doc__.strip().splitlines()[-1], file=sys.stdout if sys.argv[1] in ("-h", "--help") else sys.stderr)
    sys.exit(0 if sys.argv[1] in ("-h", "--help") else 2)

rng = np.random.default_rng(3)
side, per, ranks = 12, 24, 3
disks = []
for b in range(side * side):
    r = 0.54 * rng.uniform(0.92, 1.04)
    t = rng.uniform() + 2 * math.pi * np.arange(per) / per
    c = np.array([b % side + 0.5 + 0.04 * rng.standard_normal(), b // side + 0.5 + 0.04 * rng.standard_normal()])
    disks.append(c + r * np.stack([np.cos(t), np.sin(t)], axis=1))
nodes = np.concatenate(disks)
seg = np.concatenate([np.linalg.norm(np.roll(d, -1, axis=0) - d, axis=1) for d in disks])
median, lmax = float(np.sort(seg)[(len(seg) - 1) // 2]), float(seg.max())
halo = 2 * (median + 1.01 * lmax)
lo, hi, bins = nodes[:, 0].min(), nodes[:, 0].max(), 4096
hist = np.bincount(np.clip(((nodes[:, 0] - lo) / (hi - lo) * bins).astype(int), 0, bins - 1), minlength=bins)
cum = np.cumsum(hist)
cuts = [-np.inf] + [lo + (hi - lo) * (int(np.searchsorted(cum, len(nodes) * k / ranks)) + 1) / bins
                    for k in range(1, ranks)] + [np.inf]
owner = [(b % side) * ranks // side for b in range(len(disks))]
colors = ["#4e79a7", "#f28e2b", "#59a14f"]
fig, ax = plt.subplots(figsize=(7.2, 6.6))
s = 1
for b, d in enumerate(disks):
    x0, x1 = d[:, 0].min() - halo, d[:, 0].max() + halo
    held = x1 >= cuts[s] and x0 < cuts[s + 1]
    poly = np.vstack([d, d[:1]])
    ax.fill(poly[:, 0], poly[:, 1], color=colors[owner[b]], alpha=0.55 if held else 0.18, lw=0)
    if held:
        ax.plot(poly[:, 0], poly[:, 1], color="black", lw=0.8)
for c in cuts[1:-1]:
    ax.axvline(c, color="crimson", lw=2)
ax.axvspan(cuts[1] - halo, cuts[1], color="crimson", alpha=0.08)
ax.axvspan(cuts[2], cuts[2] + halo, color="crimson", alpha=0.08)
for k in range(ranks):
    a, b2 = max(cuts[k], -0.3), min(cuts[k + 1], side + 0.3)
    ax.text((a + b2) / 2, side + 0.35, f"slab {k}", ha="center", color="crimson", fontsize=11)
ax.set_title("3 ranks: the host owns bands of columns (colours); the library's slabs (red) follow them\n"
             "slab 1 holds the outlined bodies (its own and a halo; shaded: the halo's reach)", fontsize=10)
ax.set_aspect("equal")
ax.set_xlim(-0.6, side + 0.6)
ax.set_ylim(-0.4, side + 0.8)
ax.set_xticks([])
ax.set_yticks([])
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "distributed_slabs.png", dpi=90)
