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

-- The BENCH line, from beside this script whatever the working directory.
done = dofile((debug.getinfo(1, "S").source:match("^@(.*/)") or "./") .. "bench_line.lua")

