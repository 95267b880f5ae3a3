#!/usr/bin/env bash
# The distributed evaluation's figures (docs/distributed.md): strong scaling
# at 1e5 and 1e6 surface nodes and weak scaling (5e5 nodes a rank) on 1 and 2
# ranks, the decomposition kept (a solver's loop) and made anew every step
# (skin 0), interleaved rounds; bytes each rank sends and the halo fraction.
# Layout 0: the host owns bands of rows of disks; 1: bands of columns (the
# slabs follow either); 2: disk b on rank b mod P (no slab can follow it).
# Needs a Release build with -DNTS_MPI=ON and the bench component:
#   cmake -S . -B build-mpi-rel -DCMAKE_BUILD_TYPE=Release -DNTS_MPI=ON \
#         -DNTS_COMPONENTS="codec;cli;bench" -DNTS_FORTRAN=OFF && cmake --build build-mpi-rel
# usage: bash bench/mpi/run.sh [BUILD_DIR] [ROUNDS] > bench/results/mpi.csv
set -euo pipefail
build=${1:-build-mpi-rel}
rounds=${2:-3}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# steal: the share of the run's CPU time the VM's host took (/proc/stat's
# steal against user + system + steal): a run with much of it had less than
# its cores, and its ratios say so.
echo "round,case,layout,ranks,skin,surface_nodes,contacts,median_s,min_s,frame_s,bodies_s,evaluate_s,sums_s,bytes_sent_per_rank,halo_fraction,serial_median_s,steal"
cpu() { awk '/^cpu /{print $9, $2 + $3 + $4}' /proc/stat; }
for round in $(seq 1 "$rounds"); do
  for c in "strong1e6 25000 0" "strong1e6 25000 1" "strong1e6 25000 2" "strong1e5 2500 0" "weak 12500 0"; do
    set -- $c
    name=$1 disks=$2 layout=$3
    for skin in -1 0; do
      for np in 1 2; do
        d=$disks
        [ "$name" = weak ] && d=$((disks * np))
        c0=$(cpu)
        out=$(mpirun -np "$np" --bind-to core "$build/bin/mpi_bench" "$d" 40 9 0 "$skin" "$layout")
        c1=$(cpu)
        steal=$(echo "$c0 $c1" | awk '{ s = $3 - $1; b = $4 - $2; printf "%.3f", (s + b > 0) ? s / (s + b) : 0 }')
        line=$(echo "$out" | grep '^rebuilt')
        serial=$(echo "$out" | awk '/^nts_evaluate/ {print $5}')
        echo "$line" | awk -v r="$round" -v n="$name" -v l="$layout" -v s="$skin" -v ser="${serial:-}" -v st="$steal" '{
          for (i = 1; i <= NF; ++i) v[$i] = $(i + 1);
          printf "%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s\n", r, n, l, v["ranks"], s, v["nodes"], v["contacts"],
                 v["median_s"], v["min_s"], v["frame+slabs"], v["bodies"], v["evaluate"], v["sums"],
                 v["max_bytes_sent_per_rank"], v["halo_fraction"], ser, st }'
      done
    done
  done
done
