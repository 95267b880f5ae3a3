#!/usr/bin/env bash
# A/B/C of the threading models under the same (possibly noisy) conditions:
# alternate, for R rounds of bench/load/run.sh,
#   per-connection  a thread per connection, --threads evaluations at once
#   pool            epoll polling threads; scenes over 64 KiB on evaluation threads
#   pool-inline     the same polling threads evaluating every scene themselves
#                   (--inline-max 1G: libmicrohttpd's plain thread pool)
# then print the median of each figure per model and run.
#
#   bench/load/compare.sh [--rounds R] [--duration S]     (default 3 rounds of 5 s runs)
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=3
duration=5
while [ $# -gt 0 ]; do
  case "$1" in
    --rounds) rounds=$2; shift 2 ;;
    --duration) duration=$2; shift 2 ;;
    *) echo "usage: $0 [--rounds R] [--duration S]" >&2; exit 2 ;;
  esac
done
out=$(mktemp)
trap 'rm -f "$out"' EXIT
for r in $(seq "$rounds"); do
  for mode in per-connection pool pool-inline; do
    case $mode in
      pool-inline) flags=(--threading pool --daemon-args "--inline-max 1G") ;;
      *) flags=(--threading "$mode") ;;
    esac
    bash bench/load/run.sh "${flags[@]}" --duration "$duration" | grep -v '^#' | grep -v '^##' |
      grep -E '^(health|small|large|STALL)' | sed "s/^/$mode /" | tee -a "$out"
  done
done
echo "# medians over $rounds rounds"
python3 - "$out" <<'PY'
import collections, re, statistics, sys
rows = collections.defaultdict(lambda: collections.defaultdict(list))
for line in open(sys.argv[1]):
    parts = line.split()
    mode = parts[0]
    key = " ".join(parts[1:3]) if parts[1] != "STALL" else "stall " + parts[2]
    for k, v in re.findall(r"(\w+)=([0-9.]+)(?:ms)?", line):
        if k in ("rps", "p50_ms", "p90_ms", "p99_ms", "mean_ms", "cpu_per_req", "receiving", "handling", "sending"):
            rows[(key, mode)][k].append(float(v))
for (key, mode), figs in sorted(rows.items()):
    print(f"{key:14s} {mode:15s} " + " ".join(f"{k}={statistics.median(v):.2f}" for k, v in figs.items()))
PY
