#!/usr/bin/env bash
# Bounded libFuzzer session on ntsj_handle (decode + evaluate + encode):
#   scripts/fuzz.sh [SECONDS]      (default 60; CI runs about a minute)
# Builds fuzz/fuzz_handle with clang, ASan + UBSan (no recover) and coverage
# instrumentation into build-fuzz/ (or $NTS_FUZZ_BUILD_DIR), then fuzzes from
# the seed corpus (fuzz/corpus, fuzz/seeds, fuzz/regressions, examples/*.json)
# with the JSON dictionary. Fails (non-zero) on any crash, sanitizer report,
# leak, contract breach, per-input timeout (10 s) or memory blow-up (2 GiB);
# the input that did it is left in build-fuzz/artifacts/. New inputs go to
# build-fuzz/new-corpus (not committed; `NTS_FUZZ_MERGE=1` merges them, minimised,
# into fuzz/corpus). Needs Debian's clang and libclang-rt-*-dev.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
dir=${NTS_FUZZ_BUILD_DIR:-build-fuzz}
if ! command -v clang >/dev/null 2>&1; then
  echo "fuzz: clang is not installed (Debian: clang libclang-rt-14-dev)" >&2
  exit 1
fi
CC=clang cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DNTS_FUZZ=ON -DNTS_SANITIZE=ON \
  -DNTS_OPENMP=OFF -DNTS_BUILD_TESTS=OFF -DNTS_COMPONENTS="codec;fuzz" >/dev/null
cmake --build "$dir" -j "$(nproc)" --target fuzz_handle >/dev/null

mkdir -p "$dir/artifacts" "$dir/new-corpus" "$dir/examples"
cp examples/*.json "$dir/examples/" 2>/dev/null || true
log="$dir/fuzz.log"
set +e
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:symbolize=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  "$dir/bin/fuzz_handle" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
  -dict=fuzz/json.dict -artifact_prefix="$dir/artifacts/" -print_final_stats=1 \
  "$dir/new-corpus" fuzz/corpus fuzz/seeds fuzz/regressions "$dir/examples" >"$log" 2>&1
rc=$?
set -e
grep -E "^#[0-9]+ +(INITED|DONE)|^stat::number_of_executed_units|^stat::peak_rss_mb|^Done " "$log" | tail -n 5 || true
if [ $rc -ne 0 ]; then
  echo "fuzz: FAILED (exit $rc); the log is $log, the input in $dir/artifacts/:" >&2
  grep -E -m 20 "ERROR|SUMMARY|runtime error|contract breached|Test unit written" "$log" >&2 || true
  exit $rc
fi
if [ "${NTS_FUZZ_MERGE:-0}" = 1 ]; then
  "$dir/bin/fuzz_handle" -merge=1 -max_len=65536 fuzz/corpus "$dir/new-corpus" >>"$log" 2>&1
  echo "fuzz: merged into fuzz/corpus ($(ls fuzz/corpus | wc -l) files)"
fi
echo "fuzz: ${secs} s, no crash, leak or timeout"
