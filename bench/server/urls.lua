-- wrk script: cycles through a list of tile paths (one per line in $TILE_PATHS) under $PREFIX,
-- asking for gzip and the octvertexnormals extension as CesiumJS does, and prints one
-- machine-readable RESULT line at the end.
local paths = {}
local prefix = os.getenv("PREFIX") or ""
for line in io.lines(os.getenv("TILE_PATHS")) do paths[#paths + 1] = prefix .. line end
local counter = 0

function setup(thread)
  thread:set("offset", counter * 7919)
  counter = counter + 1
end

-- The request strings are formatted once per thread, in init() (wrk has set the Host header by
-- then), not per request: formatting in request() made the single-threaded load generator pay for
-- a Lua table and string building on every request, which in the pinned configuration (wrk alone
-- on one core) capped both servers alike (bench/server/RESULTS.md, 2026-11-25 11:00).
local reqs = {}
function init(args)
  for k, p in ipairs(paths) do
    reqs[k] = wrk.format("GET", p, {
      ["Accept-Encoding"] = "gzip",
      ["Accept"] = "application/vnd.quantized-mesh;extensions=octvertexnormals,application/octet-stream;q=0.9"})
  end
end

local i = 0
function request()
  i = i + 1
  return reqs[((i + (offset or 0)) % #reqs) + 1]
end

function done(summary, latency, requests)
  local seconds = summary.duration / 1e6
  local errors = summary.errors.connect + summary.errors.read + summary.errors.write +
                 summary.errors.status + summary.errors.timeout
  io.write(string.format("RESULT rps=%.1f p50_ms=%.3f p99_ms=%.3f max_ms=%.3f bytes=%d errors=%d requests=%d\n",
    summary.requests / seconds, latency:percentile(50) / 1000, latency:percentile(99) / 1000,
    latency.max / 1000, summary.bytes, errors, summary.requests))
end
