#!/usr/bin/env bash
# The main job: installs what serving needs, builds the server and the clients (Release), prepares
# the built-in models and serves them: the Stanford bunny and the 871k-triangle Stanford dragon. Their Multi-Tessellations
# are built into build/models on the first run and reused afterwards. The browser viewer is served
# on HTTP port $MTLOD_HTTP_PORT (default 8080). Extra arguments go to mtlod-server (e.g. --port 9000).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# Only what serving needs: the tests' packages (Chromium, podman, HAProxy, ...) and the tests and
# benchmarks themselves are scripts/test.sh's business.
"$root/scripts/bootstrap.sh" --profile build
# A unity build (sources compiled in batches) parses the heavy headers once per batch: a third less
# compilation than one source at a time (BENCHMARKS.md, "Serving from a fresh clone").
MTLOD_TARGETS="mtlod-server mtlod-client mtlod-load mtlod-gaze" \
  "$root/scripts/build.sh" release -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD=ON
"$root/scripts/prepare-models.sh"
bin="$root/build/release"
models="$root/build/models"
meshes=(--mesh "$models/bunny.ply")
[ -s "$models/dragon-871k.ply" ] && meshes+=(--mesh "$models/dragon-871k.ply")
http_port=${MTLOD_HTTP_PORT:-8080}
cat <<MSG
mtlod-server is starting on 127.0.0.1 (port 7878 unless you passed --port).
Open the viewer:  http://127.0.0.1:$http_port/   (orbit with the mouse; the pointer is the focus)
Query it with:
  $bin/clients/client/mtlod-client list
  $bin/clients/client/mtlod-client extract bunny --error-px 1 --silhouette 2,0 -o bunny.ply
  $bin/clients/load/mtlod-load --model dragon-871k --connections 4 --duration 10 --budget 50000
  $bin/clients/gaze/mtlod-gaze --model dragon-871k --streams 4 --hz 120 --error-px 0.5 --silhouette 2,0.25 --delta
Stop it with Ctrl-C (it finishes in-flight requests first).
MSG
exec "$bin/server/mtlod-server" "${meshes[@]}" --cache-dir "$models" --http-port "$http_port" "$@"
