#!/usr/bin/env python3
"""What the split of the work permits two ranks, in instructions (docs/distributed.md).

The wall-clock ratio of two ranks to one on this 2-core VM moves by 30% from
run to run; instruction counts do not. For each layout, `mpi_bench DISKS 40
R 0 -1 LAYOUT` runs under callgrind on 1 rank and on 2 ranks (`mpirun -np P
--bind-to core valgrind --tool=callgrind`), at R = R1 and R2 repeats; a
step's instructions on a rank are the difference between the two runs over
R2 - R1 steps, counting the code of mpi_bench (the core, libntscontact_mpi,
the bench) and the C library's calls, not Open MPI's (a rank waiting for
its peer spins in the MPI library; the C library's calls Open MPI makes
itself, its shared-memory copies and its event loop's waits, are counted
with ours, a small part). On one rank the bench also evaluates the
whole scene with nts_evaluate for its table; that call (from main) is taken
out. Printed per layout: one rank's instructions per node and step, each of
two ranks', their sum against one rank (the work the distribution adds) and
the largest against one rank; one rank's over the largest is the speed-up
the split permits if both cores ran at one core's speed.

usage: .venv/bin/python bench/mpi/ceiling.py [--build DIR] [--disks D] [--repeats R1 R2] [--layouts L ...]
(needs valgrind and a Release build with -DNTS_MPI=ON: see bench/mpi/run.sh)
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

ENTRY = re.compile(r"\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(\S+)(?:\s+\[(.+)\])?$")
C_LIBRARY = re.compile(r"^lib[cm]([.-]|$)")  # libc.so.6, libm.so.6, libc-2.31.so
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def ours(path, bench):
    """Exclusive instructions of the bench's own code and the C library's calls.

    A line without an object is code inlined from another source file
    (callgrind_annotate names the file, not the object): counted when that
    file is this repository's, left out otherwise (another library's
    headers; with a Release build, which has no line information, every
    line names its object)."""
    out = subprocess.run(["callgrind_annotate", "--threshold=100", path], capture_output=True, text=True,
                         check=True).stdout
    total = 0
    for line in out.splitlines():
        m = ENTRY.match(line)
        if m is None or "PROGRAM TOTALS" in line:
            continue
        if m.group(3):
            obj = os.path.basename(m.group(3))
            counted = obj == bench or C_LIBRARY.match(obj) is not None
        else:
            counted = m.group(2).startswith(ROOT + os.sep)
        if counted:
            total += int(m.group(1).replace(",", ""))
    return total


def called_from_main(path, function):
    """The inclusive instructions of `function` called from main (0 when it is not)."""
    out = subprocess.run(["callgrind_annotate", "--tree=caller", "--inclusive=yes", "--threshold=100", path],
                         capture_output=True, text=True, check=True).stdout
    for block in out.split("\n\n"):
        if not re.search(r"\*\s+\S*:%s \[" % re.escape(function), block):
            continue
        for line in block.splitlines():
            m = re.match(r"\s*([\d,]+)\s+\(.*<\s+\S*:main \(", line)
            if m:
                return int(m.group(1).replace(",", ""))
    return 0


def per_rank(tmp, build, disks, repeats, layout, ranks):
    """Each rank's instructions (ours) for one run."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    prefix = os.path.join(tmp, f"cg.L{layout}.P{ranks}.R{repeats}")
    bench = os.path.join(build, "bin", "mpi_bench")
    subprocess.run(["mpirun", "-np", str(ranks), "--bind-to", "core", "valgrind", "--tool=callgrind",
                    f"--callgrind-out-file={prefix}.%q{{OMPI_COMM_WORLD_RANK}}", bench, str(disks), "40",
                    str(repeats), "0", "-1", str(layout)], env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    counts = []
    for rank in range(ranks):
        path = f"{prefix}.{rank}"
        count = ours(path, "mpi_bench")
        if ranks == 1:
            count -= called_from_main(path, "nts_evaluate")
        counts.append(count)
    return counts


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default="build-mpi-rel")
    ap.add_argument("--disks", type=int, default=25000)
    ap.add_argument("--repeats", type=int, nargs=2, default=[2, 4])
    ap.add_argument("--layouts", type=int, nargs="+", default=[0, 1, 2])
    a = ap.parse_args()
    r1, r2 = a.repeats
    if not r2 > r1 >= 1:
        sys.exit("--repeats R1 R2: 1 <= R1 < R2")
    nodes = 40 * a.disks
    print(f"mpi_bench {a.disks} 40 R 0 -1 LAYOUT, R = {r1} and {r2}; instructions per surface node and step")
    print()
    print("| layout | 1 rank | 2 ranks (each) | 2 ranks' sum / 1 rank | largest / 1 rank | 1 rank / largest |")
    print("|---:|---:|---|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="nts-ceiling-") as tmp:
        for layout in a.layouts:
            step = {}
            for ranks in (1, 2):
                lo = per_rank(tmp, a.build, a.disks, r1, layout, ranks)
                hi = per_rank(tmp, a.build, a.disks, r2, layout, ranks)
                step[ranks] = [(h - l) / (r2 - r1) / nodes for l, h in zip(lo, hi)]
            one, two = step[1][0], step[2]
            print(f"| {layout} | {one:.0f} | {' + '.join(f'{x:.0f}' for x in two)} | {sum(two) / one:.3f} "
                  f"| {max(two) / one:.3f} | **{one / max(two):.2f}** |", flush=True)


if __name__ == "__main__":
    main()
