"""A context's memory over warm evaluations with 2 threads on a busy machine,
this tree against another commit (issue 22: the workers' buffers grew with
the schedule).

    .venv/bin/python bench/thread_memory.py --before REV [--build DIR] [--evals N] [--runs K] [--limit-mb M]

Builds `nts_cross` against REV's core as bench/default_cost.py does, then,
with one busy loop per core beside it (the schedule then deals the two
threads uneven shares of the search), runs `nts_cross memory N` of each side
K times (default 3 runs of 1,000 evaluations), each under an address-space
limit of M MB (default 3,000: a side that grows without bound stops with
"out of memory" instead of taking the machine). Prints a Markdown table: the
bytes the context holds after the 1st, 100th and last evaluation, the most,
and how the run ended."""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import default_cost  # noqa: E402  (its builder of a previous nts_cross)
import report  # noqa: E402


def run_side(exe: str, evals: int, limit_mb: int) -> dict[str, str]:
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit_mb << 20, limit_mb << 20))

    p = subprocess.run([exe, "memory", str(evals)], capture_output=True, text=True, preexec_fn=limit)
    rows = [line.split(",") for line in p.stdout.splitlines()[1:] if line]
    by_eval = {int(r[1]): r for r in rows}
    last = rows[-1] if rows else ["", "0", "", "0"]
    return {
        "nodes": last[0],
        "first": by_eval[1][2] if 1 in by_eval else "",
        "at100": by_eval[100][2] if 100 in by_eval else "",
        "last": last[2],
        "most": last[3],
        "end": "%d evaluations" % evals if p.returncode == 0 else (p.stderr.strip().split(": ", 1)[-1] or
                                                                   "exit %d" % p.returncode),
    }


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="the commit to compare with (a tag, hash or branch)")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--evals", type=int, default=1000)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--limit-mb", type=int, default=3000)
    args = ap.parse_args(argv)
    exes = {args.before: default_cost.build_cross(args.build, args.before),
            "this": os.path.join(args.build, "bin", "nts_cross")}
    t0 = time.time()
    busy = [subprocess.Popen(["sh", "-c", "while :; do :; done"]) for _ in range(os.cpu_count() or 1)]
    out = []
    try:
        for k in range(args.runs):
            for side, exe in exes.items():
                r = run_side(exe, args.evals, args.limit_mb)
                out.append([side, k + 1, r["nodes"], r["first"], r["at100"], r["last"], r["most"], r["end"]])
    finally:
        for b in busy:
            b.kill()
            b.wait()
    print("`.venv/bin/python bench/thread_memory.py --before %s --evals %d --runs %d`: %s, %d busy loops, %.0f s" % (
        args.before, args.evals, args.runs, report.sh("git rev-parse --short HEAD"), len(busy), time.time() - t0))
    print()
    print(report.table(["core", "run", "surface nodes", "bytes after 1", "after 100", "after the last", "most",
                        "end"], out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
