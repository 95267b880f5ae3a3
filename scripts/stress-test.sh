#!/usr/bin/env bash
# The whole suite (scripts/test.sh) N times in a row (default 5) on a busy
# machine: one busy loop (`yes > /dev/null`) per core runs beside it the whole
# time, so every thread of the tests, the daemon and the evaluations shares its
# core with a loop that never yields. No test may assert on timing or on a
# schedule (issue 22 §3): the suite must pass every run. Stops at the first
# failed run and says which; the logs are in $NTS_STRESS_LOGS (default
# /tmp/nts-stress).
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
case "$runs" in ''|*[!0-9]*) echo "usage: $0 [RUNS]" >&2; exit 2 ;; esac
logs=${NTS_STRESS_LOGS:-/tmp/nts-stress}
mkdir -p "$logs"
loops=()
stop_loops() { for p in "${loops[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap stop_loops EXIT
for _ in $(seq "$(nproc)"); do
  yes > /dev/null &
  loops+=($!)
done
echo "stress-test: $runs runs of scripts/test.sh beside ${#loops[@]} busy loops; logs in $logs" >&2
for k in $(seq "$runs"); do
  start=$(date +%s)
  if bash scripts/test.sh > "$logs/run-$k.log" 2>&1; then
    echo "stress-test: run $k/$runs passed in $(( $(date +%s) - start )) s" >&2
  else
    echo "stress-test: run $k/$runs FAILED after $(( $(date +%s) - start )) s; the end of $logs/run-$k.log:" >&2
    tail -n 40 "$logs/run-$k.log" >&2
    exit 1
  fi
done
echo "stress-test: all $runs runs passed" >&2
