-- wrk script: session steps, cycling over sessions created beforehand.
--   wrk -t2 -c8 -d10s -s bench/load/steps.lua http://HOST:PORT -- PATHS.txt POSITIONS.bin
-- PATHS.txt: one /v1/scenes/{id}/contact a line; POSITIONS.bin: the binary body
-- (16 N bytes, the sessions' node count). The answer is asked for in binary.
local paths = {}
local body
local counter = 0

function init(args)
   for line in io.lines(args[1]) do
      if #line > 0 then paths[#paths + 1] = line end
   end
   local f = assert(io.open(args[2], "rb"))
   body = f:read("*a")
   f:close()
end

function request()
   counter = counter + 1
   local path = paths[(counter % #paths) + 1]
   return wrk.format("POST", path, {["Content-Type"] = "application/octet-stream",
                                    ["Accept"] = "application/octet-stream"}, body)
end

-- The BENCH line, from beside this script whatever the working directory.
done = dofile((debug.getinfo(1, "S").source:match("^@(.*/)") or "./") .. "bench_line.lua")

