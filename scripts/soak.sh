#!/usr/bin/env bash
# A soak of the Release server (not part of the test suite): MINUTES of mixed extract and gaze load
# (mtlod-load, one run per minute for per-minute percentiles) with hostile traffic beside it
# (scripts/hostile.mjs), sampling the server's RSS and open descriptors every 10 s. Writes
# build/soak/report.md; fails if the server dies, a reply is lost, or an internal error occurs.
#   scripts/soak.sh [MINUTES] [MODEL]      (defaults: 30, dragon-871k)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
minutes=${1:-30}
model=${2:-dragon-871k}
out="$root/build/soak"
"$root/scripts/bootstrap.sh"
"$root/scripts/build.sh" release -DCMAKE_BUILD_TYPE=Release
"$root/scripts/prepare-models.sh"
bin="$root/build/release"
models="$root/build/models"
rm -rf "$out" && mkdir -p "$out"

"$bin/server/mtlod-server" --mesh "$models/bunny.ply" --mesh "$models/$model.ply" --cache-dir "$models" \
  --port 0 --http-port 0 --port-file "$out/port" --log-level warn >"$out/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 600); do [ -s "$out/port" ] && break; sleep 0.1; done
port=$(sed -n 1p "$out/port")
http_port=$(sed -n 2p "$out/port")

(  # resources every 10 s: seconds, RSS KiB, open descriptors
  start=$(date +%s)
  while kill -0 $server 2>/dev/null; do
    rss=$(awk '/^VmRSS:/ {print $2}' /proc/$server/status)
    echo "$(($(date +%s) - start)) $rss $(ls /proc/$server/fd | wc -l)" >>"$out/resources.tsv"
    sleep 10
  done
) &
sampler=$!

node "$root/scripts/hostile.mjs" --port "$port" --http-port "$http_port" --duration $((minutes * 60)) \
  --clients 4 >"$out/hostile.json" &
hostile=$!

for m in $(seq "$minutes"); do
  "$bin/clients/load/mtlod-load" --port "$port" --model "$model" --model bunny --connections 4 --duration 60 \
    --mix extract=3,gaze=1 --error-px 1 --silhouette 2,0.25 --seed "$m" --quiet --json "$out/load-$m.json" \
    >/dev/null
done
wait $hostile
"$bin/clients/client/mtlod-client" --port "$port" stats >"$out/stats.txt"
kill -TERM $server
wait $server && status=0 || status=$?
kill $sampler 2>/dev/null || true
trap - EXIT

node - "$out" "$minutes" "$status" <<'JS'
const fs = require('fs');
const [dir, minutes, status] = process.argv.slice(2);
const rows = [], resources = fs.readFileSync(`${dir}/resources.tsv`, 'utf8').trim().split('\n').map((l) => l.split(' ').map(Number));
let lost = 0, sent = 0, ok = 0, internal = 0;
for (let m = 1; m <= Number(minutes); ++m) {
  const r = JSON.parse(fs.readFileSync(`${dir}/load-${m}.json`, 'utf8'));
  const at = resources.filter(([s]) => s <= m * 60).pop() ?? [0, 0, 0];
  lost += r.lost; sent += r.sent; ok += r.ok; internal += r.errors_by_code?.internal ?? 0;
  rows.push(`| ${m} | ${r.ok} | ${r.errors} | ${r.lost} | ${r.latency_ms.p50.toFixed(1)} | ${r.latency_ms.p99.toFixed(1)} | ` +
            `${r.latency_ms.max.toFixed(1)} | ${(at[1] / 1024).toFixed(0)} | ${at[2]} |`);
}
const hostile = fs.readFileSync(`${dir}/hostile.json`, 'utf8').trim();
const report = [
  `Soak: ${minutes} min, server exit status ${status}; load: ${sent} sent, ${ok} meshes, ${lost} lost, ${internal} internal errors; hostile: ${hostile}`,
  '', '| minute | meshes | errors | lost | p50 ms | p99 ms | max ms | RSS MiB | fds |', '| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |',
  ...rows].join('\n');
fs.writeFileSync(`${dir}/report.md`, report + '\n');
console.log(report);
process.exit(status === '0' && lost === 0 && internal === 0 ? 0 : 1);
JS
