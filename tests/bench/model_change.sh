#!/usr/bin/env bash
# What changing a served model's file costs (BENCHMARKS.md, "Models that change"): a Release
# mtlod-server serves MT (default: the 871k dragon's, built by scripts/run.sh) while mtlod-gaze
# streams from it; the file is then replaced ROUNDS times by `cp` over it (in place: the lease is
# broken, the model retired, the file handed over, the new file loaded when cp closes it) and
# ROUNDS times by `mv` of a copy written beside it (a new inode: the old version serves until the
# new one is loaded). Prints per way: the writer's wall time (cp: including its wait for the
# hand-over; mv: the rename alone), the hand-over (from the server's log), the time from the
# writer's start until `list` shows the new version, and the gaze streams' replies.
#   tests/bench/model_change.sh [MT] [ROUNDS]
#   GAZE_MS: how long the streams run; GAZE_FLAGS: more mtlod-gaze flags (--budget 40000 for 105M)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
mt=${1:-$root/build/models/dragon-871k.mt}
rounds=${2:-10}
bin=$root/build/release
work=${WORK:-$root/build/model-change}
rm -rf "$work" && mkdir -p "$work/models"
name=$(basename "$mt" .mt)
cp "$mt" "$work/copy.mt"
cp "$mt" "$work/models/$name.mt"
"$bin/server/mtlod-server" --models "$work/models" --port 0 --port-file "$work/port" >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 600); do [ -s "$work/port" ] && break; sleep 0.1; done
port=$(sed -n 1p "$work/port")
client=("$bin/clients/client/mtlod-client" --port "$port")

version() { "${client[@]}" list | awk -v n="$name" '$1 == n {print $NF}'; }
now_ms() { date +%s%3N; }

# The streams must outlast the rounds: GAZE_MS (default 1.5 s per round and 6 s more); a file of
# gigabytes takes seconds per cp.
"$bin/clients/gaze/mtlod-gaze" --port "$port" --model "$name" --streams 4 --hz 120 \
  --duration "${GAZE_MS:-$(((rounds * 2 + 4) * 1500))}" ${GAZE_FLAGS:-} --json "$work/gaze.json" \
  >"$work/gaze.log" 2>&1 &
gaze=$!
sleep 2
for way in cp mv; do
  for _ in $(seq "$rounds"); do
    before=$(version)
    [ "$way" = mv ] && cp "$work/copy.mt" "$work/next.tmp"  # written beside first, not timed
    start=$(now_ms)
    if [ "$way" = cp ]; then
      cp "$work/copy.mt" "$work/models/$name.mt"
    else
      mv "$work/next.tmp" "$work/models/$name.mt"
    fi
    written=$(now_ms)
    while [ "$(version)" = "$before" ]; do sleep 0.005; done
    echo "$way $((written - start)) $(($(now_ms) - start))" >>"$work/rounds.txt"
    sleep 0.5
  done
done
wait $gaze || true
kill -TERM $server
wait $server || true
trap - EXIT

echo "| way | writer's wall time, median ms | hand-over, median ms | new version listed after, median ms |"
echo "| --- | ---: | ---: | ---: |"
median() { sort -n | awk '{a[NR] = $1} END {print (NR ? a[int((NR + 1) / 2)] : "-")}'; }
for way in cp mv; do
  writer=$(awk -v w=$way '$1 == w {print $2}' "$work/rounds.txt" | median)
  listed=$(awk -v w=$way '$1 == w {print $3}' "$work/rounds.txt" | median)
  handover=-
  [ "$way" = cp ] && handover=$(grep -o 'handed over after [0-9.]* ms' "$work/server.log" | awk '{print $4}' | median)
  echo "| $way | $writer | $handover | $listed |"
done
node -e 'const r = JSON.parse(require("fs").readFileSync(process.argv[1], "utf8"));
  console.log(`gaze: ${r.meshes} meshes, errors ${JSON.stringify(r.errors_by_code)}, lost ${r.lost}, latency p99 ${r.latency_ms.p99.toFixed(1)} ms`);' \
  "$work/gaze.json"
