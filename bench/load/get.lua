-- wrk script: GET (for /v1/health: the cost of HTTP alone). Same BENCH line as post.lua.

-- The BENCH line, from beside this script whatever the working directory.
done = dofile((debug.getinfo(1, "S").source:match("^@(.*/)") or "./") .. "bench_line.lua")

