#!/usr/bin/env bash
# The scaling benchmark (tests/bench/BENCHMARKS.md, "Scaling"): generates inputs of 1M to 100M
# triangles, builds each with mtlod-build under a memory limit and prints one Markdown row per input:
# build wall time, rate, peak RSS, bytes per input triangle at the peak, .mt size, temporary files.
# Inputs are generated into WORK (default build/scale) and deleted after their row unless KEEP=1.
#   Usage: tests/bench/scale.sh [SIZES...]   sizes: 1M 4M 16M 64M (shells) and dragon105M (the
#          871k dragon split 11 × 11 with noise); default all of them. MEMORY_LIMIT=4G by default.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
tools=$root/build/release/clients/tools
work=${WORK:-$root/build/scale}
limit=${MEMORY_LIMIT:-4G}
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(1M 4M 16M 64M dragon105M)
[ -x "$tools/mtlod-build" ] || "$root/scripts/build.sh" release -DCMAKE_BUILD_TYPE=Release
"$root/scripts/prepare-models.sh"
mkdir -p "$work"

echo "| input | triangles | build wall | M tri/s | peak RSS | bytes / input tri at peak | .mt file | temporary files |"
echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
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
  [ "${KEEP:-0}" = 1 ] || rm -f "$input" "$work/$size.mt"
done
