#!/usr/bin/env bash
# Start the HTTP service ntscontactd, query it once with the bundled example
# (examples/two_disks.json, with curl), print a summary, and leave the daemon
# running in the foreground until Ctrl-C (it then finishes what is in flight
# and exits 0).
#
#   scripts/serve-demo.sh [--port N | --port=N] [--once]
#
# --port N   listen on 127.0.0.1:N (default 8080, or $NTS_PORT; 0 = any free port;
#            when the default 8080 is busy, any free port is taken)
# --once     stop after the query instead of staying in the foreground
# Builds first (scripts/install-deps.sh + scripts/build.sh) when the daemon is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

port=${NTS_PORT:-8080}
port_given=${NTS_PORT:+1}
once=0
while [ $# -gt 0 ]; do
  case "$1" in
    --port) [ $# -ge 2 ] || { echo "serve-demo: option '--port' needs a value" >&2; exit 2; }
            port=$2; port_given=1; shift 2 ;;
    --port=*) port=${1#--port=}; port_given=1; shift ;;
    --once) once=1; shift ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "serve-demo: unknown argument: $1" >&2; exit 2 ;;
  esac
done

build=${NTS_BUILD_DIR:-build}
daemon="$build/bin/ntscontactd"
if [ ! -x "$daemon" ]; then
  bash scripts/install-deps.sh
  NTS_BUILD_DIR="$build" bash scripts/build.sh
fi
example=examples/two_disks.json

out=$(mktemp)
log=$(mktemp) # the daemon's log lines, shown after the summary (not between it and the curl line)
pid=""
tailer=""
cleanup() {
  [ -n "$pid" ] && kill -TERM "$pid" 2>/dev/null && wait "$pid" 2>/dev/null
  [ -n "$tailer" ] && kill "$tailer" 2>/dev/null
  # (the log read first, then removed, then shown: a reader gone from stderr,
  # as in `serve-demo.sh --once | head`, must not leave the files behind)
  local shown=""
  [ -s "$log" ] && [ "$once" = 1 ] && shown=$(cat "$log")
  rm -f "$out" "$log"
  [ -n "$shown" ] && printf '%s\n' "$shown" >&2 2>/dev/null
  return 0
}
trap cleanup EXIT

start() { # port
  "$daemon" --host 127.0.0.1 --port "$1" >"$out" 2>"$log" &
  pid=$!
  for _ in $(seq 100); do
    grep -q "listening on" "$out" 2>/dev/null && return 0
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.05
  done
  wait "$pid" 2>/dev/null || true
  pid=""
  cat "$log" >&2
  : >"$log"
  return 1
}
if ! start "$port"; then
  if [ -z "$port_given" ]; then
    echo "serve-demo: port $port is busy; taking any free port" >&2
    start 0 || { echo "serve-demo: ntscontactd did not start" >&2; exit 1; }
  else
    if [[ "$port" =~ ^[0-9]{1,4}$ ]] && ((10#$port > 0 && 10#$port < 1024)) && [ "$(id -u)" -ne 0 ]; then
      echo "serve-demo: ntscontactd did not start on port $port: ports below 1024 need root; try --port 8080 or --port 0" >&2
    else
      echo "serve-demo: ntscontactd did not start on port $port (busy? try --port 0)" >&2
    fi
    exit 1
  fi
fi
bound=$(sed -n 's/.*listening on //p' "$out")
url="http://$bound"

echo "== ntscontactd on $url =="
echo "\$ curl -s -H 'Content-Type: application/json' --data-binary @$example $url/v1/contact"
result=$(curl -sS --max-time 60 -H 'Content-Type: application/json' --data-binary @"$example" "$url/v1/contact")
health=$(curl -sS --max-time 10 "$url/v1/health")
python3 - "$result" "$health" <<'PY'
import json, sys
r, h = json.loads(sys.argv[1]), json.loads(sys.argv[2])
if "error" in r:
    sys.exit(f"error: {r['error']}")
s = r["summary"]
v = s["virial"]
print(f"scene:    {s['bodies']} bodies, {s['surface_nodes']} surface nodes")
print(f"contacts: {s['contacts']} active (g < 0), {s['gaps']} closest points within r = {s['search_radius']:.4g}")
print(f"energy:   {s['energy']:.6g}   max penetration {s['max_penetration']:.4g}")
print(f"virial:   xx {v['xx']:.6g}  yy {v['yy']:.6g}  xy {v['xy']:.6g}")
print(f"time:     {s['elapsed_ms']:.3f} ms in the codec and core")
print(f"server:   ntscontactd {h['version']}, {h['server']['threading']} threading, "
      f"{h['server']['threads']} evaluation threads, {h['requests_served']} request(s) served before "
      "this health query")
PY
echo
echo "Also: $url/v1/health  $url/v1/openapi.json  $url/v1/schemas/{scene,result,error,session}  POST $url/v1/validate"
echo "      POST $url/v1/scenes (a session; then POST .../v1/scenes/{id}/contact with new positions, docs/sessions.md)"

if [ "$once" = 1 ]; then
  exit 0
fi
echo "ntscontactd keeps running in the foreground; Ctrl-C to stop. Its log (the requests so far, then each one):"
tail -n +1 -f "$log" >&2 &
tailer=$!
# Ctrl-C reaches the daemon too (same process group); it finishes what is in
# flight and exits 0. Wait for it, through the interruption of `wait` itself.
trap '' INT
status=0
while kill -0 "$pid" 2>/dev/null; do
  wait "$pid" && status=0 || status=$?
done
pid=""
exit "$status"
