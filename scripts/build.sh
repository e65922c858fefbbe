#!/usr/bin/env bash
# Configures and builds mtlod into build/<name>. Usage: scripts/build.sh NAME [cmake options...]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
name=$1
shift
# ccache keys on relative paths below the checkout, so a fresh clone elsewhere still hits the cache.
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=true
cmake -S "$root" -B "$root/build/$name" "$@" >/dev/null
cmake --build "$root/build/$name" -j "$(nproc)"
