#!/usr/bin/env bash
# The main job: installs what is missing, builds mtlod (Release), prepares the built-in models and
# prints their statistics.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/scripts/bootstrap.sh"
"$root/scripts/build.sh" release -DCMAKE_BUILD_TYPE=Release
"$root/scripts/prepare-models.sh"
bin="$root/build/release/core"
"$bin/mtlod-mesh" "$root/build/models/bunny.ply"
"$bin/mtlod-mesh" "$root/build/models/dragon-871k.ply"
