#!/usr/bin/env python3
"""Issue 27's "today's evaluation", measured: release 0.2 (41e9e21) beside this tree in a solver's loop.

    .venv/bin/python bench/release_loop.py [--quick] [--build DIR] [--before REV] [--rounds N] [--steps S] [--per-build K ...]

Issue 27 was measured on release 0.2 and states its targets against "today's
evaluation": a kept step at most 0.5 of it (section 1) and an evaluation from
scratch of 60 ns a node against 0.2's 105-125 (section 2, a ratio of 0.48 to
0.57). The issue's 0.2 is commit 41e9e21, the last before issue 22's work (its
1,214 instructions a node; 0.2.0 as first written, 691e656, is slower still).
Absolute nanoseconds depend on the machine; this script measures that commit
itself on this one, on kept_bench's scenes and motion:

- `nts_cross loop` (bench/cross.c) built against release 0.2 (REV, default
  41e9e21, a Release build from git by bench/report.py's helpers under
  BUILD/release-REV) and
  against this tree (BUILD/bin/nts_cross): each step gives the positions to the
  scene and evaluates from scratch with the release's default options, one
  thread;
- `kept_bench` of this tree (BUILD/bin/kept_bench): the same loop with a kept
  candidate list, positions in one call (nts_evaluate_positions).

A round runs the three one after the other, in an order rotated from round to
round, for each K (steps between a kept list's builds, eq. (29)); each ratio
is taken within its round. All three time the same steps (S warm, then 3 of
S), each figure the median over those 3 of the mean over their steps. Prints a
Markdown table per K. 41e9e21 finds fewer contacts at the same radius (its
default dropped the active contacts deeper than the radius: issue 22), so it
does less work than this tree.
"""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import types

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import report  # noqa: E402  (build_previous, build_previous_cross: release 0.2 from git)

ROOT = report.ROOT


def loop_rows(exe, args, per_build):
    """nts_cross loop: {surface_nodes: row}."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "loop.csv")
        cmd = [exe, "loop", path, "--steps", str(args.steps), "--rounds", "3", "--per-build", str(per_build)]
        if args.quick:
            cmd.append("--quick")
        subprocess.run(cmd, check=True, env=dict(os.environ, OMP_NUM_THREADS="1"))
        return {int(r["surface_nodes"]): r for r in report.read_csv(path)}


def kept_rows(exe, args, per_build):
    """kept_bench (3 rounds of its own, the steps nts_cross loop --rounds 3 times):
    {surface_nodes: (scratch eval ns, kept step ns, contacts)}."""
    cmd = [exe, "--rounds", "3", "--steps", str(args.steps), "--per-build", str(per_build)]
    if args.quick:
        cmd.append("--quick")
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    rows = {}
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 7 and re.fullmatch(r"\d+", cells[0]):
            rows[int(cells[0])] = (float(cells[3]), float(cells[6]), int(cells[1]))
    return rows


def spread(v):
    return "%.3f (%.3f-%.3f)" % (statistics.median(v), min(v), max(v))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="1e4 and 1e5 nodes only")
    ap.add_argument("--build", default=os.path.join(ROOT, "build-bench"),
                    help="a Release build of this tree with the bench component")
    ap.add_argument("--before", default="41e9e21", help="release 0.2 as issue 27 measured it")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--per-build", type=float, nargs="+", default=[10.0, 5.0])
    args = ap.parse_args()
    log = []
    # a directory per release: report.py's helpers keep a library they find built
    prev = types.SimpleNamespace(build=os.path.join(args.build, "release-" + re.sub(r"\W", "_", args.before)),
                                 before=args.before)
    report.build_previous(prev, log, "Release")  # as this tree's build: the same compiler flags
    old = report.build_previous_cross(prev, log)
    cur = os.path.join(args.build, "bin", "nts_cross")
    kept = os.path.join(args.build, "bin", "kept_bench")
    for k in args.per_build:
        got = []
        for j in range(args.rounds):
            # the three programs in a rotated order each round (a drift of the
            # machine's speed hits each at every place)
            runs = [lambda: loop_rows(old, args, k), lambda: loop_rows(cur, args, k), lambda: kept_rows(kept, args, k)]
            got_j = [None] * 3
            for q in range(3):
                got_j[(q + j) % 3] = runs[(q + j) % 3]()
            a, b, c = got_j
            for n in a:
                if a[n]["search_radius"] != b[n]["search_radius"]:
                    raise SystemExit("not the same scene: radius %s against %s" % (a[n]["search_radius"],
                                                                                  b[n]["search_radius"]))
            got.append((a, b, c))
        print("\nK = %g steps between builds (%d rounds of %d steps; release %s)\n" % (k, args.rounds, args.steps,
                                                                                    args.before))
        r = args.before
        print("| surface nodes | contacts %s / now | %s: evaluation ns/node | now: evaluation from scratch "
              "ns/node (nts_cross; kept_bench) | now: kept step ns/node | kept step / %s's evaluation (median; "
              "range) | evaluation from scratch / %s's (median; range) |" % (r, r, r, r))
        print("|---:|---|---:|---|---:|---|---|")
        for n in sorted(got[0][0]):
            e02 = [float(g[0][n]["eval_ns"]) for g in got]
            enow = [float(g[1][n]["eval_ns"]) for g in got]
            knot = [g[2][n][1] for g in got]
            kscratch = [g[2][n][0] for g in got]
            print("| %d | %s / %s | %.1f | %.1f; %.1f | %.1f | %s | %s |" % (
                n, got[0][0][n]["contacts"], got[0][1][n]["contacts"], statistics.median(e02),
                statistics.median(enow), statistics.median(kscratch), statistics.median(knot),
                spread([x / y for x, y in zip(knot, e02)]), spread([x / y for x, y in zip(enow, e02)])))
        sys.stdout.flush()
    print("\n" + "; ".join(log), file=sys.stderr)


if __name__ == "__main__":
    main()
