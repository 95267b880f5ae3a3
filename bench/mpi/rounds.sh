#!/usr/bin/env bash
# Issue 30's measured target, in alternated rounds: for each round and each
# layout of the host's bodies (0: bands of rows, 1: bands of columns, 2:
# body b on rank b mod 2), `mpi_bench 25000 40 9 0 -1 LAYOUT` (1e6 surface
# nodes, the decomposition kept) on one rank, then on two ranks bound to
# cores; each round's ratio is taken within the round (one rank's step over
# two ranks'), then the median per layout. With -np 1 mpi_bench also times
# one process's nts_evaluate, printed beside. docs/distributed.md, "On the
# VM of 2026-11-30".
# Needs a Release build with -DNTS_MPI=ON (bench/mpi/run.sh says how).
# usage: bash bench/mpi/rounds.sh [BUILD_DIR] [ROUNDS]
set -euo pipefail
build=${1:-build-mpi-rel}
rounds=${2:-5}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
step() { awk '/^rebuilt/ { for (i = 1; i <= NF; ++i) if ($i == "median_s") print $(i + 1) }'; }
out=$(mktemp)
trap 'rm -f "$out"' EXIT
echo "round,layout,one_rank_s,two_ranks_s,ratio,nts_evaluate_s"
for r in $(seq 1 "$rounds"); do
  for layout in 0 1 2; do
    one_out=$(mpirun -np 1 --bind-to core "$build/bin/mpi_bench" 25000 40 9 0 -1 "$layout")
    one=$(echo "$one_out" | step)
    serial=$(echo "$one_out" | awk '/^nts_evaluate/ {print $5}')
    two=$(mpirun -np 2 --bind-to core "$build/bin/mpi_bench" 25000 40 9 0 -1 "$layout" | step)
    ratio=$(awk -v a="$one" -v b="$two" 'BEGIN { printf "%.3f", a / b }')
    echo "$r,$layout,$one,$two,$ratio,$serial" | tee -a "$out"
  done
done
for layout in 0 1 2; do
  awk -F, -v l="$layout" '$2 == l { print $5 }' "$out" | sort -n |
    awk -v l="$layout" '{ v[NR] = $1 } END { m = NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2;
                          printf "# layout %s: two ranks / one, median %.3f (rounds %.3f-%.3f)\n", l, m, v[1], v[NR] }'
done
