"""Throughput of 1, 2 and 3 ntscontactd behind nginx (deploy/nginx.conf).

    .venv/bin/python bench/scale_out.py [--duration 5] [--threads-per-daemon 1] [--write docs/benchmarks.md]

For each daemon count: full scenes (POST /v1/contact, 10x10 pressed disks of
64 nodes, 6,400 nodes) and session steps (binary, 2x2 disks of 32 nodes, 16
sessions spread over the daemons by nginx), with wrk (8 connections, 2
threads), through nginx; and, as the reference, the same loads on one daemon
directly. Needs nginx and wrk (scripts/install-deps.sh installs both). Every daemon gets
--threads-per-daemon evaluation threads, so that the count of daemons, not
of threads, is what changes."""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import time

import numpy as np
import requests

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "deploy"))
sys.path.insert(0, str(REPO / "bench" / "sessions"))
import cluster  # noqa: E402
from common import replace_section  # noqa: E402

BUILD = pathlib.Path(os.environ.get("NTS_BUILD_DIR", str(REPO / "build")))


def wrk(url: str, script: str, args, duration: int) -> dict:
    out = subprocess.run(["wrk", "-t2", "-c8", f"-d{duration}s", "-s", script, url, "--", *map(str, args)],
                         capture_output=True, text=True, timeout=duration + 60).stdout
    line = next(x for x in out.splitlines() if x.startswith("BENCH "))
    return {k: float(v) for k, v in re.findall(r"(\w+)=([\d.]+)", line)}


def run_loads(base: str, work: pathlib.Path, large: pathlib.Path, small: dict, duration: int) -> dict:
    full = wrk(base + "/v1/contact", str(REPO / "bench/load/post.lua"), [large], duration)
    paths = []
    for _ in range(16):
        r = requests.post(base + "/v1/scenes", json=small, timeout=30)
        r.raise_for_status()
        paths.append(r.headers["Location"] + "/contact")
    (work / "paths.txt").write_text("\n".join(paths) + "\n")
    pos = np.concatenate([np.asarray(b["nodes"], dtype="<f8") for b in small["bodies"]]) + 0.001
    (work / "pos.bin").write_bytes(pos.astype("<f8").tobytes())
    steps = wrk(base, str(REPO / "bench/load/steps.lua"), [work / "paths.txt", work / "pos.bin"], duration)
    for p in paths:
        requests.delete(base + p[: -len("/contact")], timeout=30)
    return {"full": full, "steps": steps}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=int, default=5)
    ap.add_argument("--threads-per-daemon", type=int, default=1)
    ap.add_argument("--write", help="replace the section in this markdown file")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="nts-scale-") as tmp:  # (scenes, logs, nginx's files: all removed)
        return run(args, pathlib.Path(tmp))


def run(args: argparse.Namespace, work: pathlib.Path) -> int:
    large = work / "large.json"
    large.write_text(subprocess.run([sys.executable, str(REPO / "bench/load/make_scene.py"), "--side", "10",
                                     "--nodes", "64"], capture_output=True, text=True, check=True).stdout)
    small = json.loads(subprocess.run([sys.executable, str(REPO / "bench/load/make_scene.py"), "--side", "2",
                                       "--nodes", "32"], capture_output=True, text=True, check=True).stdout)
    flags = ["--quiet", "--threads", str(args.threads_per_daemon), "--max-sessions", "256"]
    rows = []
    # The reference: one daemon, no proxy.
    with cluster.Cluster(BUILD / "bin/ntscontactd", work / "direct", 1, flags) as c:
        rows.append(("1, direct (no nginx)", run_loads(c.daemon_url(0), work, large, small, args.duration)))
    for n in (1, 2, 3):
        with cluster.Cluster(BUILD / "bin/ntscontactd", work / f"n{n}", n, flags) as c:
            rows.append((f"{n} behind nginx", run_loads(c.url, work, large, small, args.duration)))
    load = open("/proc/loadavg").read().split()[:3]
    lines = [
        "## Scale-out behind nginx",
        "",
        f"`.venv/bin/python bench/scale_out.py --duration {args.duration} --threads-per-daemon {args.threads_per_daemon}` "
        f"({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, load average "
        f"{' '.join(load)} after the run): nginx 1.22 with `deploy/nginx.conf` in front of N daemons of "
        f"`--threads {args.threads_per_daemon}` each, wrk with 8 connections. *Full*: POST /v1/contact of 10x10 "
        "pressed disks (6,400 nodes). *Steps*: binary session steps of 2x2 disks (128 nodes) over 16 sessions "
        "that nginx spreads by id.",
        "",
        "| daemons | full scenes / s | p99 ms | steps / s | p99 ms | non-2xx |",
        "|---|---|---|---|---|---|",
    ]
    for name, r in rows:
        lines.append(f"| {name} | {r['full']['rps']:.0f} | {r['full']['p99_ms']:.1f} | {r['steps']['rps']:.0f} | "
                     f"{r['steps']['p99_ms']:.1f} | {int(r['full']['non2xx'] + r['steps']['non2xx'])} |")
    lines.append("")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        replace_section(args.write, "## Scale-out behind nginx", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
