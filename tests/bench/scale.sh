#!/usr/bin/env bash
# The scaling benchmark (tests/bench/BENCHMARKS.md, "Scaling"): generates inputs of 1M to 100M
# triangles, builds each with mtlod-build under a memory limit and prints one Markdown row per input:
# build wall time, rate, peak RSS, bytes per input triangle at the peak, .mt size, temporary files.
# Then it serves each .mt with the Release mtlod-server and prints a second table, one row per
# input: start-up, server RSS, extraction stages at a fixed cut size and at an error bound, an
# orbiting camera on one connection, gaze p99.
# Inputs are generated into WORK (default build/scale) and deleted after their row unless KEEP=1.
#   Usage: tests/bench/scale.sh [SIZES...]   sizes: 1M 4M 16M 64M (shells) and dragon105M (the
#          871k dragon split 11 × 11 with noise); default all of them. MEMORY_LIMIT=4G by default.
#          tests/bench/scale.sh --serve FILE.mt...   only the serving table, for MTs built before
#          (a run with KEEP=1 leaves them in WORK; the 100M build alone takes minutes). SERVE=0: only
#          the build table. Both tables need an otherwise idle machine: the stages are a few ms.
#   Serving knobs: REQUESTS=50 extracts of each kind (so 100 before the RSS column), GAZE_SECONDS=10,
#   ORBIT_REQUESTS=300 views per orbit, SERVER_FLAGS="--max-memory 16G" (more mtlod-server flags).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
tools=$root/build/release/clients/tools
server=$root/build/release/server/mtlod-server
client=$root/build/release/clients/client/mtlod-client
gaze=$root/build/release/clients/gaze/mtlod-gaze
load=$root/build/release/clients/load/mtlod-load
work=${WORK:-$root/build/scale}
limit=${MEMORY_LIMIT:-4G}
requests=${REQUESTS:-50}
gaze_seconds=${GAZE_SECONDS:-10}
orbit_requests=${ORBIT_REQUESTS:-300}
# The two extractions, from the front view mtlod-client frames when given no --eye. The budgeted one
# has the load table's criteria (--silhouette 2,0): the full-resolution silhouette band alone
# passes 10k triangles, so the budget binds and every model gets a cut of the same size. The
# error-bound one has mtlod-gaze's criteria (issue #24): its cut size is whatever the model needs.
budget_flags=(--error-px 1 --silhouette "2,0" --budget 10000)
error_flags=(--error-px 0.5 --silhouette "2,0.25")

serve_files=()
if [ "${1:-}" = --serve ]; then
  shift
  serve_files=("$@")
  [ ${#serve_files[@]} -gt 0 ] || { echo "usage: $0 --serve FILE.mt..." >&2; exit 2; }
  sizes=()
else
  sizes=("$@")
  [ ${#sizes[@]} -gt 0 ] || sizes=(1M 4M 16M 64M dragon105M)
fi
for binary in "$tools/mtlod-build" "$tools/mtlod-gen" "$server" "$client" "$gaze"; do
  [ -x "$binary" ] || { "$root/scripts/build.sh" release -DCMAKE_BUILD_TYPE=Release; break; }
done
[ ${#sizes[@]} -eq 0 ] || "$root/scripts/prepare-models.sh"
mkdir -p "$work"

# One server at a time; whatever way the script ends (an error under set -e, Ctrl-C), it is stopped.
server_pid=
stop_server() {
  [ -n "$server_pid" ] || return 0
  local pid=$server_pid status=0
  server_pid=
  kill -TERM "$pid" 2>/dev/null || true
  # SIGTERM drains for up to --drain-timeout-ms (10 s); an idle server exits at once.
  for _ in $(seq 150); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  if kill -0 "$pid" 2>/dev/null; then
    echo "mtlod-server $pid ignored SIGTERM for 15 s; killing it" >&2
    kill -KILL "$pid" 2>/dev/null || true
  fi
  wait "$pid" 2>/dev/null || status=$?
  [ "$status" = 0 ] || echo "mtlod-server exited with status $status" >&2
}
trap stop_server EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

rss_mib() { awk '/^VmRSS:/ { printf "%.0f", $2 / 1024 }' "/proc/$1/status"; }
peak_rss_mib() { awk '/^VmHWM:/ { printf "%.0f", $2 / 1024 }' "/proc/$1/status"; }
ms_since() { awk -v a="$1" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.0f", (b - a) * 1000 }'; }

# Medians of one kind of extraction. Reads mtlod-client's output for each request (its lines
# "NAME: T triangles, ..." and "server µs: queue Q map M ... total T; round trip R ms") and prints
# one table cell group: cut triangles | before encoding | the stages | untimed, times in ms.
# Each figure is its own median over the requests. Before encoding is map + occupancy + DT + allowed
# error + refine (BENCHMARKS.md's stage table). Untimed is the server's total less the queue and the
# six stages: setting up the connection's session (a new Refiner per connection) and the hand-offs
# between the strand and the worker, so a part that grows with the model shows there too.
stage_medians() {
  awk '
    function median(a,   i, k, m, v, tmp) {
      for (i = 1; i <= n; i++) v[i] = a[i]
      for (i = 2; i <= n; i++) {  # insertion sort: a few dozen requests
        tmp = v[i]
        for (k = i - 1; k > 0 && v[k] > tmp; k--) v[k + 1] = v[k]
        v[k + 1] = tmp
      }
      m = int((n + 1) / 2)
      return n % 2 ? v[m] : (v[m] + v[m + 1]) / 2
    }
    / triangles, .* vertices, / { tri = $2 }
    /^server µs:/ {
      n++; cut[n] = tri
      map[n] = $6 / 1000; occ[n] = $8 / 1000; dt[n] = $10 / 1000
      labels[n] = $12 / 1000; refine[n] = $14 / 1000; encode[n] = $16 / 1000
      before[n] = map[n] + occ[n] + dt[n] + labels[n] + refine[n]
      untimed[n] = ($18 - $4) / 1000 - before[n] - encode[n]
    }
    END {
      if (n == 0) { printf "– | – | – | –"; exit }
      printf "%d | %.2f | %.3f / %.2f / %.2f / %.2f / %.2f / %.2f | %.2f", median(cut), median(before),
        median(map), median(occ), median(dt), median(labels), median(refine), median(encode), median(untimed)
    }' "$1"
}

# Serves one MT alone and adds its row of the serving table to serve_rows (in this shell, not a
# $(...) subshell, so that the EXIT trap knows the server). Its files go to WORK/NAME.serve/.
serve_row() {
  local mt=$1 name port_file out t0 port
  name=$(basename "$mt" .mt)
  out=$work/$name.serve
  rm -rf "$out" && mkdir -p "$out"
  port_file=$out/port
  # Start-up, from exec: to the port file, written once the model is loaded and the socket listens
  # (polled every 10 ms), and to the first answered request, a list from a new mtlod-client (which
  # adds its own start and connection, about 30 ms here). The page cache holds the MT when it was
  # just built; after --serve it may not.
  t0=$EPOCHREALTIME
  # shellcheck disable=SC2086  # SERVER_FLAGS is a list of flags, e.g. "--max-memory 16G"
  "$server" "$mt" --host 127.0.0.1 --port 0 --port-file "$port_file" --log-format json ${SERVER_FLAGS:-} \
    >"$out/server.log" 2>&1 &
  server_pid=$!
  until [ -s "$port_file" ]; do
    kill -0 "$server_pid" 2>/dev/null || { cat "$out/server.log" >&2; echo "mtlod-server did not start on $mt" >&2; exit 1; }
    sleep 0.01
  done
  local listen_ms start_ms rss_start triangles
  listen_ms=$(ms_since "$t0")
  port=$(head -1 "$port_file")
  "$client" --port "$port" --attempts 1 list >/dev/null
  start_ms=$(ms_since "$t0")
  rss_start=$(rss_mib "$server_pid")
  triangles=$("$client" --port "$port" info "$name" | sed -n 's/^.*: [0-9]* vertices, \([0-9]*\) input triangles.*/\1/p')

  # A fresh connection per request (one mtlod-client each), as a new viewer or a new view costs: the
  # connection's session is built from nothing every time. The first request also pays for the
  # worker's per-model scratch; it has its own column (server total). A refused or failed request
  # (limit_exceeded when the model is large for --max-memory) is counted, not fatal.
  local i failed=0 first_ms rss_after session
  for ((i = 0; i < requests; i++)); do
    "$client" --port "$port" --attempts 1 extract "$name" "${budget_flags[@]}" >>"$out/budget.txt" 2>>"$out/errors.txt" ||
      failed=$((failed + 1))
  done
  for ((i = 0; i < requests; i++)); do
    "$client" --port "$port" --attempts 1 extract "$name" "${error_flags[@]}" >>"$out/error.txt" 2>>"$out/errors.txt" ||
      failed=$((failed + 1))
  done
  rss_after=$(rss_mib "$server_pid")
  first_ms=$(awk '/^server µs:/ { printf "%.1f ms", $18 / 1000; found = 1; exit } END { if (!found) printf "–" }' "$out/budget.txt")
  # What one connection holds on the server after a 10k-triangle cut (memory.session_bytes).
  session=$(awk '/^server memory:/ { print $3 }' "$out/budget.txt" | sort -g |
    awk '{ v[NR] = $1 } END { if (NR) printf "%.1f MiB", NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2; else printf "–" }')

  # An orbiting camera on one connection: mtlod-load's random cameras around the model, a new view
  # per request, delta replies; the cost of a new view once the connection's session exists. The
  # same views are run twice and the second run is measured: the first checks the mapped blocks
  # they reach (a model's first views pay for that, as the first-extract column shows). Mean cut
  # and mean server time before encoding (map, occupancy, transforms, allowed error, refine).
  orbit() {
    "$load" --port "$port" --model "$name" -c 1 -n "$orbit_requests" -d 600 -q --delta "$@" \
      >/dev/null 2>>"$out/errors.txt" &&
      "$load" --port "$port" --model "$name" -c 1 -n "$orbit_requests" -d 600 -q --delta "$@" \
        --json "$out/orbit.json" >"$out/orbit.txt" 2>>"$out/errors.txt" &&
      jq -r '[.mean_triangles, (.server_us | .map + .occupancy + .dt + .labels + .refine) / 1000,
              .errors + .lost] | @tsv' "$out/orbit.json" |
      awk '{ printf "%.0f: %.2f ms", $1, $2; if ($3 > 0) printf " (%d failed)", $3 }' || printf "–"
  }
  local orbit_error orbit_budget
  orbit_error=$(orbit "${error_flags[@]}")
  orbit_budget=$(orbit "${budget_flags[@]}")

  # Gaze streams as README's mtlod-gaze example and BENCHMARKS.md's gaze table: 4 × 120 Hz, deltas.
  local gaze_cells="– | –" gaze_failed=all
  if "$gaze" --port "$port" --model "$name" --streams 4 --hz 120 --duration "$((gaze_seconds * 1000))" \
    "${error_flags[@]}" --delta --quiet --json "$out/gaze.json" >"$out/gaze.txt" 2>>"$out/errors.txt"; then
    gaze_cells=$(jq -r '[.latency_ms.p99, .mean_triangles] | @tsv' "$out/gaze.json" | awk '{ printf "%.1f | %.0f", $1, $2 }')
    gaze_failed=$(jq '.errors + .lost' "$out/gaze.json")
  fi
  # Read after mtlod-gaze has closed its connections: what the server keeps of their sessions (freed
  # memory the allocator holds included); the peak covers them while open.
  local rss_gaze peak
  rss_gaze=$(rss_mib "$server_pid")
  peak=$(peak_rss_mib "$server_pid")
  stop_server
  [ "$failed" = 0 ] && [ "$gaze_failed" = 0 ] || echo "$name: failed requests, see $out/errors.txt and gaze.json" >&2

  local budget_cells error_cells
  budget_cells=$(stage_medians "$out/budget.txt")
  error_cells=$(stage_medians "$out/error.txt")
  serve_rows+=("$(printf '| %s | %s | %s / %s ms | %s MiB | %s MiB | %s | %s | %s | %s | %s | %s | %s | %s / %s MiB | %s / %s |' \
    "$name" "$triangles" "$listen_ms" "$start_ms" "$rss_start" "$rss_after" "$first_ms" "$budget_cells" "$session" \
    "$error_cells" "$orbit_error" "$orbit_budget" "$gaze_cells" "$rss_gaze" "$peak" "$failed" "$gaze_failed")")
}

serve_rows=()
if [ ${#sizes[@]} -gt 0 ]; then
  echo "| input | triangles | build wall | M tri/s | peak RSS | bytes / input tri at peak | .mt file | temporary files |"
  echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
fi
for size in "${sizes[@]}"; do
  input=$work/$size.ply
  case $size in
    dragon105M) "$tools/mtlod-gen" --from "$root/build/models/dragon-871k.ply" --split 11 -o "$input" >/dev/null ;;
    *M) "$tools/mtlod-gen" --shape shell --triangles "${size%M}000000" -o "$input" >/dev/null ;;
    *) echo "unknown size $size" >&2; exit 2 ;;
  esac
  log=$work/$size.log
  /usr/bin/time -v "$tools/mtlod-build" "$input" -o "$work/$size.mt" --memory-limit "$limit" >"$log" 2>&1
  triangles=$(sed -n 's/^.*: [0-9]* vertices, \([0-9]*\) triangles$/\1/p' "$log" | head -1)
  seconds=$(sed -n 's/^  built in \([0-9.]*\) s.*/\1/p' "$log")
  temp=$(sed -n 's/.*temporary files up to \([0-9]*\) MiB.*/\1/p' "$log")
  rss_kb=$(sed -n 's/^\s*Maximum resident set size (kbytes): //p' "$log")
  mt_bytes=$(stat -c %s "$work/$size.mt")
  awk -v n="$size" -v t="$triangles" -v s="$seconds" -v r="$rss_kb" -v m="$mt_bytes" -v tmp="$temp" 'BEGIN {
    printf "| %s | %d | %.1f s | %.2f | %.2f GiB | %.0f | %.2f GiB | %.2f GiB |\n",
      n, t, s, t / s / 1e6, r / 1048576, r * 1024 / t, m / 2^30, tmp / 1024 }'
  # The input is not needed to serve; deleting it first leaves the disk (and page cache) to the MT.
  [ "${KEEP:-0}" = 1 ] || rm -f "$input"
  [ "${SERVE:-1}" = 0 ] || serve_row "$work/$size.mt"
  [ "${KEEP:-0}" = 1 ] || rm -f "$work/$size.mt"
done
for mt in "${serve_files[@]}"; do serve_row "$mt"; done

if [ ${#serve_rows[@]} -gt 0 ]; then
  [ ${#sizes[@]} -eq 0 ] || echo
  echo "| input | triangles | start: listening / first reply | RSS at start | RSS after $((2 * requests)) extracts | first extract (server total) | 10k budget: cut | before encoding ms | map / occupancy / DT / allowed error / refine / encode ms | untimed ms | connection's session | 0.5 px: cut | before encoding ms | map / occupancy / DT / allowed error / refine / encode ms | untimed ms | orbit 0.5 px: cut, before encoding | orbit 10k budget: cut, before encoding | gaze-to-mesh p99 ms | gaze cut | RSS after gaze / peak | failed extracts / gazes |"
  echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
  printf '%s\n' "${serve_rows[@]}"
fi
