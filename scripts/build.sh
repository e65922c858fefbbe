#!/usr/bin/env bash
# Configures and builds mtlod into build/<name>. Usage: scripts/build.sh NAME [cmake options...]
# $MTLOD_TARGETS (space-separated) builds only those targets and what they need; default: all.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
name=$1
shift
# ccache keys on relative paths below the checkout, so a fresh clone elsewhere still hits the cache.
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=true
cmake -S "$root" -B "$root/build/$name" "$@" >/dev/null
targets=()
for target in ${MTLOD_TARGETS:-}; do targets+=(--target "$target"); done
cmake --build "$root/build/$name" -j "$(nproc)" "${targets[@]}"
