"""The default evaluation of this tree against another commit's, run one after
the other, round by round (issue 22: the default radius finds every contact;
what does that cost?).

    .venv/bin/python bench/default_cost.py --before REV [--build DIR] [--rounds N] [--quick] [--csv FILE]

Builds `nts_cross` (bench/cross.c, the same program) against REV's core the way
bench/report.py does (a git worktree under BUILD/prev-REV), then runs
`nts_cross time` of REV and of this tree in turn, N rounds (default 5): the
periodic benchmark packings of about 1e4, 1e5 and 1e6 surface nodes at alpha 0
and 0.2, one thread, default options, median CPU time per surface node of a
warm evaluation. Prints a Markdown table: per row the medians over the rounds,
the median and the range of each round's own ratio (this tree over REV, run
back to back, so load that comes and goes between rounds cancels), and each
side's active contacts: a ratio is at equal work only where they agree."""
from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
import types

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import report  # noqa: E402  (its builders of a previous core)


def build_cross(build: str, before: str) -> str:
    """nts_cross against REV's core, in BUILD/prev-REV."""
    rev = report.sh("git rev-parse --short %s^{commit}" % before)
    if not rev:
        raise SystemExit("--before %s: not a commit of this repository" % before)
    sub = os.path.join(build, "prev-" + rev)
    os.makedirs(sub, exist_ok=True)
    args = types.SimpleNamespace(build=sub, before=before)
    log: list[str] = []
    report.build_previous(args, log)
    return report.build_previous_cross(args, log)


def run_rounds(exes: dict[str, str], rounds: int, quick: bool) -> dict[str, dict]:
    rows: dict[str, dict] = {side: {} for side in exes}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            for side, exe in exes.items():
                path = os.path.join(tmp, "%s_%d.csv" % (side, k))
                p = subprocess.run([exe, "time", path] + (["--quick"] if quick else []), capture_output=True,
                                   text=True)
                if p.returncode != 0:
                    raise SystemExit("nts_cross time failed (%s): %s" % (side, p.stderr))
                for r in report.read_csv(path):
                    rows[side].setdefault((int(r["surface_nodes"]), float(r["alpha"])), []).append(r)
            sys.stderr.write("round %d of %d done\n" % (k + 1, rounds))
    return rows


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="the commit to compare with (a tag, hash or branch)")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--csv")
    args = ap.parse_args(argv)
    exes = {"before": build_cross(args.build, args.before), "after": os.path.join(args.build, "bin", "nts_cross")}
    t0 = time.time()
    rows = run_rounds(exes, args.rounds, args.quick)
    out = []
    for key in sorted(rows["after"]):
        b = [float(r["eval_cpu_ns"]) for r in rows["before"][key]]
        a = [float(r["eval_cpu_ns"]) for r in rows["after"][key]]
        ratios = [x / y for x, y in zip(a, b)]
        out.append({
            "surface_nodes": key[0], "alpha": key[1], "rounds": len(a),
            "before_ns": statistics.median(b), "after_ns": statistics.median(a),
            "ratio_median": statistics.median(ratios), "ratio_min": min(ratios), "ratio_max": max(ratios),
            "before_contacts": int(rows["before"][key][0]["contacts"]),
            "after_contacts": int(rows["after"][key][0]["contacts"]),
        })
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(out[0]))
            w.writeheader()
            w.writerows(out)
    print("`.venv/bin/python bench/default_cost.py --before %s --rounds %d%s`: %s, load %s, %.0f s" % (
        args.before, args.rounds, " --quick" if args.quick else "", report.sh("git rev-parse --short HEAD"),
        report.sh("cat /proc/loadavg"),
        time.time() - t0))
    print()
    print(report.table(
        ["surface nodes", "alpha", "%s ns/node" % args.before, "this ns/node", "ratio (median of rounds)",
         "ratio range", "%s contacts" % args.before, "this contacts"],
        [[r["surface_nodes"], "%.1f" % r["alpha"], "%.1f" % r["before_ns"], "%.1f" % r["after_ns"],
          "%.3f" % r["ratio_median"], "%.3f-%.3f" % (r["ratio_min"], r["ratio_max"]), r["before_contacts"],
          r["after_contacts"]] for r in out]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
