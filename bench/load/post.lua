-- wrk script: POST one scene file to ntscontactd, again and again.
--   wrk -t2 -c8 -d10s -s bench/load/post.lua http://127.0.0.1:PORT/v1/contact -- scene.json
-- done() prints one machine-readable line (BENCH ...) besides wrk's own report.

local scene_path

function init(args)
   scene_path = args[1]
   if scene_path == nil then
      error("usage: wrk ... -s post.lua URL -- SCENE.json")
   end
   local f = assert(io.open(scene_path, "rb"))
   wrk.method = "POST"
   wrk.body = f:read("*a")
   f:close()
   wrk.headers["Content-Type"] = "application/json"
end

function done(summary, latency, requests)
   local seconds = summary.duration / 1e6
   local errors = summary.errors
   io.write(string.format(
      "BENCH requests=%d seconds=%.2f rps=%.1f mean_ms=%.3f p50_ms=%.3f p90_ms=%.3f p99_ms=%.3f max_ms=%.3f non2xx=%d socket_errors=%d\n",
      summary.requests, seconds, summary.requests / seconds, latency.mean / 1e3,
      latency:percentile(50) / 1e3, latency:percentile(90) / 1e3, latency:percentile(99) / 1e3,
      latency.max / 1e3, errors.status, errors.connect + errors.read + errors.write + errors.timeout))
end
