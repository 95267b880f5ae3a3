#!/usr/bin/env bash
# Bounded load test of ntscontactd on 127.0.0.1 (wrk, fixed duration per run).
#
#   bench/load/run.sh [--daemon-args "FLAGS"] [--duration S] [--quick]
#
# Starts build/bin/ntscontactd (or $NTS_BUILD_DIR/bin) on a free port, then runs,
# each for S seconds (default 10):
#   health        GET /v1/health, 1 and 8 connections (HTTP alone)
#   small         POST /v1/contact, 2x2 disks x 32 nodes (128 nodes), 1 and 8 connections
#   large         POST /v1/contact, 30x30 disks x 64 nodes (57,600 nodes), 1 and 4 connections
# and the stage split of the same two scenes by ntscontact_codec_bench (when built).
#   stall         GET /v1/health latency while 4 clients post the large scene (more than the cores)
# and prints one BENCH/STALL line per run. Needs wrk (scripts/install-deps.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/../.."
daemon_args=""
duration=10
while [ $# -gt 0 ]; do
  case "$1" in
    --daemon-args) daemon_args=$2; shift 2 ;;
    --duration) duration=$2; shift 2 ;;
    --quick) duration=3; shift ;;
    *) echo "usage: $0 [--daemon-args FLAGS] [--duration S] [--quick]" >&2; exit 2 ;;
  esac
done
build=${NTS_BUILD_DIR:-build}
daemon="$build/bin/ntscontactd"
command -v wrk >/dev/null || bash scripts/install-deps.sh >&2 || exit 2
command -v wrk >/dev/null || { echo "run.sh: wrk not found (scripts/install-deps.sh installs it)" >&2; exit 2; }
[ -x "$daemon" ] || { echo "run.sh: $daemon not built" >&2; exit 2; }

work=$(mktemp -d)
pid=""
cleanup() { [ -n "$pid" ] && kill "$pid" 2>/dev/null && wait "$pid" 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT

python3 bench/load/make_scene.py --side 2 --nodes 32 >"$work/small.json"
python3 bench/load/make_scene.py --side 30 --nodes 64 >"$work/large.json"

# shellcheck disable=SC2086 # daemon_args is a list of flags
"$daemon" --port 0 --quiet $daemon_args >"$work/out" 2>"$work/err" &
pid=$!
for _ in $(seq 50); do grep -q listening "$work/out" 2>/dev/null && break; sleep 0.1; done
port=$(sed -n 's/.*:\([0-9]*\)$/\1/p' "$work/out")
[ -n "$port" ] || { echo "run.sh: the daemon did not start" >&2; cat "$work/err" >&2; exit 1; }
url="http://127.0.0.1:$port"
echo "# ntscontactd $daemon_args on $url, $(nproc) cores, ${duration}s per run"
echo "# load average before: $(cut -d" " -f1-3 /proc/loadavg)"
echo "# small: $(wc -c <"$work/small.json") bytes, large: $(wc -c <"$work/large.json") bytes"

health() { curl -s --max-time 10 "$url/v1/health"; }
# CPU seconds (user + system) the daemon has used: robust to a busy machine.
cpu() { awk -v hz="$(getconf CLK_TCK)" '{ printf "%.4f", ($14 + $15) / hz }' "/proc/$pid/stat"; }
# Server-side split of one run from the health counters before and after it:
# share of the server's time receiving, handling (codec + core), sending.
split() { # before after cpu_before cpu_after
  python3 - "$1" "$2" "$3" "$4" <<'PY'
import json, sys
a, b = (json.loads(x) for x in sys.argv[1:3])
cpu = float(sys.argv[4]) - float(sys.argv[3])
n = b["requests_served"] - a["requests_served"] - 1  # the health request in between
d = {k: b["time_s"][k] - a["time_s"][k] for k in ("receiving", "handling", "sending")}
t = sum(d.values()) or 1e-12
print(f"cpu_per_req={1e3 * cpu / max(n, 1):.3f}ms " +
      " ".join(f"{k}={1e3 * v / max(n, 1):.3f}ms({100 * v / t:.0f}%)" for k, v in d.items()))
PY
}
run() { # name connections script path [scene]
  local name=$1 c=$2 script=$3 path=$4 scene=${5:-}
  local t=$(( c < 2 ? 1 : 2 ))
  local line before after c0 c1
  before=$(health)
  c0=$(cpu)
  line=$(timeout $((duration + 30)) wrk -t"$t" -c"$c" -d"${duration}s" --timeout 30s -s "bench/load/$script" \
         "$url$path" ${scene:+-- "$scene"} | grep '^BENCH')
  c1=$(cpu)
  after=$(health)
  echo "$name c=$c ${line#BENCH } | server: $(split "$before" "$after" "$c0" "$c1")"
}
run health 1 get.lua /v1/health
run health 8 get.lua /v1/health
run small 1 post.lua /v1/contact "$work/small.json"
run small 8 post.lua /v1/contact "$work/small.json"
run large 1 post.lua /v1/contact "$work/large.json"
run large 4 post.lua /v1/contact "$work/large.json"
timeout $((duration + 60)) python3 bench/load/stall.py "$port" "$work/large.json" --busy 4 --seconds "$duration"

# Where the time goes inside one request, same scenes: the codec's stage bench.
if [ -x "$build/bin/ntscontact_codec_bench" ]; then
  echo "# stage split (ntscontact_codec_bench SIDE NODES 5: best of 5, ns per node)"
  echo "## small"; "$build/bin/ntscontact_codec_bench" 2 32 200
  echo "## large"; "$build/bin/ntscontact_codec_bench" 30 64 5
fi
