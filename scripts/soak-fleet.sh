#!/usr/bin/env bash
# The fleet soak (tests/bench/BENCHMARKS.md, "Models that change"; not part of the test suite): two
# Release replicas behind HAProxy running docker/haproxy.cfg (PROXY protocol v2), for MINUTES:
#   - 16 gaze streams (mtlod-gaze --delta, 120 Hz, one run per minute), 8 on the dragon, 8 on a
#     model whose file is changed every 10 s;
#   - 4 viewers: the real viewer page in headless Chromium through HAProxy's HTTP port, 2 per
#     model, orbiting (scripts/soak-viewers.mjs);
#   - the changing model's file truncated, rewritten by cp, overwritten with random bytes, restored,
#     deleted, renamed over (twice) and replaced by a directory, one way every 10 s, in turn;
#   - one replica killed (SIGKILL) every 5 minutes and started again 5 s later.
# Samples each replica's RSS every 10 s. Writes build/soak-fleet/report.md; fails if a replica dies
# unasked, a payload fails to decode (gaze delta_errors, a viewer's error) or a reply is lost.
#   scripts/soak-fleet.sh [MINUTES]     (default 30)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
minutes=${1:-30}
out="$root/build/soak-fleet"
"$root/scripts/bootstrap.sh"
MTLOD_TARGETS="mtlod-server mtlod-client mtlod-gaze mtlod-build mtlod-gen" \
  "$root/scripts/build.sh" release -DCMAKE_BUILD_TYPE=Release
"$root/scripts/prepare-models.sh"
bin="$root/build/release"
tools="$bin/clients/tools"
rm -rf "$out" && mkdir -p "$out/models" "$out/contents"

# The models: the dragon, and two contents for the changing one (the bunny, a generated sphere).
"$tools/mtlod-build" "$root/build/models/dragon-871k.ply" -o "$out/models/dragon.mt" >/dev/null
"$tools/mtlod-build" "$root/build/models/bunny.ply" -o "$out/contents/a.mt" >/dev/null
"$tools/mtlod-gen" --shape sphere -n 60000 -o "$out/contents/sphere.ply" >/dev/null
"$tools/mtlod-build" "$out/contents/sphere.ply" -o "$out/contents/b.mt" >/dev/null
cp "$out/contents/a.mt" "$out/models/changing.mt"

free_port() { node -e 's=require("net").createServer().listen(0,"127.0.0.1",()=>{console.log(s.address().port);s.close()})'; }
lb=$(free_port) lb_http=$(free_port) stats=$(free_port)
declare -A port http pid
for r in 1 2; do port[$r]=$(free_port); http[$r]=$(free_port); done

start_replica() {
  "$bin/server/mtlod-server" --models "$out/models" --port "${port[$1]}" --http-port "${http[$1]}" \
    --proxy-protocol-from 127.0.0.1/32 --name "replica-$1" --log-level warn >>"$out/replica-$1.log" 2>&1 &
  pid[$1]=$!
}
start_replica 1
start_replica 2
export MTLOD_BIND=127.0.0.1 MTLOD_LB_PORT=$lb MTLOD_LB_HTTP_PORT=$lb_http MTLOD_LB_STATS_PORT=$stats
export MTLOD_REPLICA_1_HOST=127.0.0.1 MTLOD_REPLICA_1_PORT=${port[1]} MTLOD_REPLICA_1_HTTP_PORT=${http[1]}
export MTLOD_REPLICA_2_HOST=127.0.0.1 MTLOD_REPLICA_2_PORT=${port[2]} MTLOD_REPLICA_2_HTTP_PORT=${http[2]}
haproxy -f "$root/docker/haproxy.cfg" >"$out/haproxy.log" 2>&1 &
haproxy=$!
cleanup() { kill "${pid[1]}" "${pid[2]}" $haproxy 2>/dev/null || true; jobs -p | xargs -r kill 2>/dev/null || true; }
trap cleanup EXIT
sleep 3

: >"$out/events.log"
crashes=0
end=$(($(date +%s) + minutes * 60))
start=$(date +%s)

(  # the changing model, one way every 10 s
  file="$out/models/changing.mt" a="$out/contents/a.mt" b="$out/contents/b.mt" step=0
  while [ "$(date +%s)" -lt "$end" ]; do
    case $((step % 9)) in
      0) for _ in $(seq 50); do truncate -s 0 "$file" 2>/dev/null && break; sleep 0.1; done; what="truncate" ;;
      1) cp "$b" "$file"; what="cp over (b)" ;;
      2) dd if=/dev/urandom of="$file" bs=65536 count=$(($(stat -c %s "$file") / 65536 + 1)) conv=notrunc status=none
         what="random bytes in place" ;;
      3) cp "$a" "$file"; what="cp over (a)" ;;
      4) rm -f "$file"; what="rm" ;;
      5) cp "$b" "$file.tmp" && mv "$file.tmp" "$file"; what="mv over (b)" ;;
      6) cp "$a" "$file.tmp" && mv "$file.tmp" "$file"; what="mv over (a)" ;;
      7) rm -f "$file" && mkdir "$file"; what="replaced by a directory" ;;
      8) rmdir "$file" && cp "$b" "$file"; what="directory removed, cp (b)" ;;
    esac
    echo "$(($(date +%s) - start)) $what" >>"$out/events.log"
    step=$((step + 1))
    sleep 10
  done
) &

(  # RSS of each replica every 10 s: seconds, replica, pid, RSS KiB
  while [ "$(date +%s)" -lt "$end" ]; do
    for r in 1 2; do
      p=$(pgrep -f -- "--name replica-$r" | head -1 || true)
      [ -n "$p" ] && echo "$(($(date +%s) - start)) $r $p $(awk '/^VmRSS:/ {print $2}' /proc/$p/status 2>/dev/null)" >>"$out/rss.tsv"
    done
    sleep 10
  done
) &

node "$root/scripts/soak-viewers.mjs" --port "$lb_http" --duration $((minutes * 60)) --models dragon,changing \
  --viewers 4 --out "$out/viewers.json" >"$out/viewers.log" 2>&1 &
viewers=$!

# One model's gaze streams for a minute. mtlod-gaze gives up when its first extract fails, which it
# does while the changing model is removed or being rewritten: it starts again 2 s later, for
# what is left of the minute (a run that gave up counts in gaze.log, not as an error).
gaze_minute() {
  local model=$1 m=$2 attempt=0 until=$(($(date +%s) + 60))
  while [ "$(date +%s)" -lt $((until - 2)) ]; do
    attempt=$((attempt + 1))
    "$bin/clients/gaze/mtlod-gaze" --port "$lb" --model "$model" --streams 8 --hz 120 \
      --duration $(((until - $(date +%s)) * 1000)) --delta --seed "$m" \
      --json "$out/gaze-$model-$m-$attempt.json" >/dev/null 2>>"$out/gaze.log" && return 0
    echo "$(($(date +%s) - start)) gaze on $model gave up at its start; again in 2 s" >>"$out/events.log"
    sleep 2
  done
}

(  # gaze streams, one run per minute and model
  m=0
  while [ "$(date +%s)" -lt "$end" ]; do
    m=$((m + 1))
    gaze_minute dragon "$m" &
    gaze_minute changing "$m" &
    wait
  done
) &
gazes=$!

# The kills: every 5 minutes one replica, in turn, started again 5 s later. A replica that exits
# between kills is a crash.
next_kill=$((start + 300)) victim=1
while [ "$(date +%s)" -lt "$end" ]; do
  for r in 1 2; do
    if ! kill -0 "${pid[$r]}" 2>/dev/null; then
      crashes=$((crashes + 1))
      echo "$(($(date +%s) - start)) replica $r exited unasked: $(tail -3 "$out/replica-$r.log" | tr '\n' ' ')" >>"$out/events.log"
      start_replica "$r"
    fi
  done
  if [ "$(date +%s)" -ge "$next_kill" ]; then
    kill -KILL "${pid[$victim]}"
    wait "${pid[$victim]}" 2>/dev/null || true
    echo "$(($(date +%s) - start)) killed replica $victim" >>"$out/events.log"
    sleep 5
    start_replica "$victim"
    victim=$((3 - victim)) next_kill=$((next_kill + 300))
  fi
  sleep 1
done
wait $gazes || true
wait $viewers || true

node - "$out" "$crashes" <<'JS'
const fs = require('fs');
const [dir, crashes] = process.argv.slice(2);
const gaze = { meshes: 0, errors: {}, delta_errors: 0, lost: 0, reconnects: 0, runs: 0 };
for (const f of fs.readdirSync(dir).filter((f) => f.startsWith('gaze-') && f.endsWith('.json'))) {
  const r = JSON.parse(fs.readFileSync(`${dir}/${f}`, 'utf8'));
  gaze.runs += 1;
  gaze.meshes += r.meshes ?? 0;
  gaze.delta_errors += r.delta_errors ?? 0;
  gaze.lost += r.lost ?? 0;
  gaze.reconnects += r.reconnects ?? 0;
  for (const [code, n] of Object.entries(r.errors_by_code ?? {})) gaze.errors[code] = (gaze.errors[code] ?? 0) + n;
}
const viewers = JSON.parse(fs.readFileSync(`${dir}/viewers.json`, 'utf8'));
const rss = fs.readFileSync(`${dir}/rss.tsv`, 'utf8').trim().split('\n').map((l) => l.split(' ').map(Number));
const byPid = new Map();
for (const [s, r, pid, kib] of rss) {
  if (!byPid.has(pid)) byPid.set(pid, { replica: r, first: [s, kib], last: [s, kib], max: kib });
  const e = byPid.get(pid);
  e.last = [s, kib];
  e.max = Math.max(e.max, kib);
}
const lines = ['# Fleet soak', '', `crashes (replicas that exited unasked): ${crashes}`, '',
  `gaze: ${gaze.runs} runs, ${gaze.meshes} meshes, delta errors ${gaze.delta_errors}, lost ${gaze.lost}, reconnects ${gaze.reconnects}, errors ${JSON.stringify(gaze.errors)}`,
  `viewers: ${JSON.stringify(viewers)}`, '',
  '| replica | pid | from s | to s | RSS first MiB | RSS last MiB | RSS max MiB |', '| --- | --- | ---: | ---: | ---: | ---: | ---: |'];
for (const [pid, e] of byPid) {
  lines.push(`| ${e.replica} | ${pid} | ${e.first[0]} | ${e.last[0]} | ${(e.first[1] / 1024).toFixed(1)} | ${(e.last[1] / 1024).toFixed(1)} | ${(e.max / 1024).toFixed(1)} |`);
}
fs.writeFileSync(`${dir}/report.md`, lines.join('\n') + '\n');
console.log(lines.join('\n'));
const failed = Number(crashes) > 0 || gaze.delta_errors > 0 || gaze.lost > 0 || viewers.decode_errors > 0 ||
  (gaze.errors.internal ?? 0) > 0;
process.exit(failed ? 1 : 0);
JS
