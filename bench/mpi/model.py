"""The distributed evaluation's cost model (docs/distributed.md), fitted to
bench/results/mpi.csv (bench/mpi/run.sh on this machine) and used to predict
the step time and the efficiency for 1e6-1e9 surface nodes on 1-1,024 ranks.

Measured, per step (the kept decomposition, the host's bodies in bands along
the slabs: layout 1):
  a   seconds of work per surface node on one rank (frame, positions,
      evaluation, sums: the 1-rank step / N);
  h1  halo surface entries per slab boundary per sqrt(N) (a boundary of the
      square packing crosses sqrt(N / 40) disks of 40 nodes; each body there
      is sent whole): 2-rank halo fraction x (N / 2) / sqrt(N);
  b1  bytes a rank sends per boundary per sqrt(N) (positions of the halo's
      bodies, the boundary contacts' force shares, the shared chunks' sums).
Parameters of the network, not measured here (one machine): the latency of
one collective round alpha and the bandwidth beta. A step makes R collective
rounds (about 30: the frame's 8 byte-histogram rounds, the agreements, the
exchanges), each log2(P) deep, and every rank receives every chunk's sums
(N / 1024 chunks, 64 bytes each) and the chunk map (4 bytes each).

  T(N, P) = a (N / P) (1 + 2 h1 sqrt(N) P / N)              compute, halo included
          + R alpha ceil(log2 P)                             latency
          + (2 b1 sqrt(N) + 68 N / 1024) / beta              bytes

with one boundary for P = 2 and two for P > 2; efficiency T(N, 1) / (P T(N, P)).
usage: python bench/mpi/model.py [bench/results/mpi.csv] > table (markdown)
"""
from __future__ import annotations

import csv
import math
import statistics
import sys
from collections import defaultdict

ALPHA = 5e-6    # s per collective round (a cluster interconnect; a parameter)
BETA = 5e9      # bytes per second per rank (a parameter)
ROUNDS = 30     # collective rounds per step


def fit(path: str) -> dict:
    rows = list(csv.DictReader(open(path)))
    by = defaultdict(list)
    for r in rows:
        by[(r["case"], r["layout"], r["skin"], r["ranks"])].append(r)
    one = by[("strong1e6", "1", "-1", "1")]
    two = by[("strong1e6", "1", "-1", "2")]
    n = float(one[0]["surface_nodes"])
    t1 = statistics.median(float(r["median_s"]) for r in one)
    t2 = statistics.median(float(r["median_s"]) for r in two)
    serial = statistics.median(float(r["serial_median_s"]) for r in one if r["serial_median_s"])
    halo = statistics.median(float(r["halo_fraction"]) for r in two)
    sent = statistics.median(float(r["bytes_sent_per_rank"]) for r in two)
    return {"n": n, "t1": t1, "t2": t2, "serial": serial, "a": t1 / n,
            "h1": halo * (n / 2) / math.sqrt(n), "b1": sent / math.sqrt(n)}


def step_time(p: dict, n: float, ranks: int) -> float:
    boundaries = 0 if ranks == 1 else (1 if ranks == 2 else 2)
    halo = boundaries * p["h1"] * math.sqrt(n)
    compute = p["a"] * (n / ranks + halo)
    latency = ROUNDS * ALPHA * math.ceil(math.log2(ranks)) if ranks > 1 else 0.0
    data = (boundaries * p["b1"] * math.sqrt(n) + 68.0 * n / 1024) / BETA if ranks > 1 else 0.0
    return compute + latency + data


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] in ("-h", "--help"):
        print((__doc__ or "").strip() + "\n\nusage: %s [MPI_CSV (default bench/results/mpi.csv)]" % sys.argv[0])
        return
    p = fit(sys.argv[1] if len(sys.argv) > 1 else "bench/results/mpi.csv")
    print(f"Fitted: a = {p['a'] * 1e9:.0f} ns per surface node (1 rank: {p['t1']:.3f} s at {p['n']:.0f} nodes; "
          f"one process's nts_evaluate {p['serial']:.3f} s), h1 = {p['h1']:.2f} halo entries per boundary per "
          f"sqrt(N), b1 = {p['b1']:.0f} bytes per boundary per sqrt(N); measured 2 ranks {p['t2']:.3f} s "
          f"(model {step_time(p, p['n'], 2):.3f} s). Network parameters: alpha = {ALPHA * 1e6:.0f} us per "
          f"collective round, beta = {BETA / 1e9:.0f} GB/s, {ROUNDS} rounds a step.\n")
    ranks = [1, 2, 4, 16, 64, 256, 1024]
    print("| surface nodes | " + " | ".join(f"{r} rank{'s' if r > 1 else ''}" for r in ranks) + " |")
    print("|---:|" + "---:|" * len(ranks))
    for n in (1e6, 1e7, 1e8, 1e9):
        t1 = step_time(p, n, 1)
        cells = []
        for r in ranks:
            if n / r < 40 * 4 * math.sqrt(n / 40):  # slabs thinner than about 4 disks: beyond the 1D decomposition
                cells.append("-")
                continue
            t = step_time(p, n, r)
            cells.append(f"{t:.3g} s ({100 * t1 / (r * t):.0f}%)")
        print(f"| {n:.0e} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
