#!/usr/bin/env bash
# Open-ended fuzzing with libFuzzer (clang) under ASan+UBSan in build/fuzz. Starts from the committed
# corpus (tests/fuzz/corpus/TARGET) and, when the time is up, merges into it the new inputs that add
# coverage, and appends the campaign's own statistics (libFuzzer's final stats, the build's commit)
# to tests/fuzz/campaigns/TARGET.tsv, the record BENCHMARKS.md quotes.
# Usage: [SANITIZE=LIST] [RUNS=N] scripts/fuzz.sh [TARGET] [SECONDS]
#   TARGET: server_stream (default), server_messages, process_tcp, process_websocket, process_http,
#   process_tls, request, frame, meshopt_decode or mt_format; SECONDS: 300.
#   SANITIZE=undefined builds in build/fuzz-undefined without ASan, for long campaigns (about 2.5 times
#   the executions per second). RUNS=N stops after N executions instead of at the time limit.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
target=${1:-server_stream}
seconds=${2:-300}
sanitize=${SANITIZE:-address,undefined}
build=$root/build/fuzz
[[ $sanitize == address,undefined ]] || build=$root/build/fuzz-${sanitize//,/-}
runs=${RUNS:--1}
binary=$build/tests/mtlod_fuzz_$target
corpus=$root/tests/fuzz/corpus/$target
# The process targets start from the seeds of the imitating targets that read the same input.
case $target in
  process_tcp) corpus=$root/tests/fuzz/corpus/server_stream ;;
  process_websocket) corpus=$root/tests/fuzz/corpus/server_messages ;;
esac
found=$build/corpus/$target  # everything this run finds; merged into $corpus at the end
export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=true
# Campaigns of both server targets may start together: one configures and builds while the other
# waits for it (the lock file sits beside the build directory, which may not exist yet).
mkdir -p "$(dirname "$build")"
(
  flock 9
  CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMTLOD_FUZZ=ON \
    -DMTLOD_SANITIZE="$sanitize" -DMTLOD_BENCHMARKS=OFF >/dev/null
  cmake --build "$build" --target "mtlod_fuzz_$target" -j "$(nproc)"
) 9>"$build.lock"
mkdir -p "$corpus" "$found" "$build/crashes"
# Under `nice`, yield to builds even when started in a session of its own (setsid): the scheduler
# shares the CPU between sessions first (autogroups), whatever the nice value inside each.
[[ $(nice) == 0 ]] || echo "$(nice)" >/proc/self/autogroup 2>/dev/null || true
dict=()
case $target in server_* | process_tcp | process_websocket | process_tls | request) dict=(-dict="$root/tests/fuzz/server.dict") ;; esac
# Crashes land in build/fuzz/crashes; replay one with: $binary FILE
# SIGINT (kill -INT) ends a campaign early and still merges what it found; SIGSTOP does not pause
# one, since libFuzzer counts the stopped time against the unit and reports a timeout.
commit=$(git -C "$root" rev-parse --short HEAD)
git -C "$root" diff --quiet HEAD -- core protocol server tests/fuzz ':!tests/fuzz/corpus' ':!tests/fuzz/campaigns' ||
  commit="$commit+changes"
log=$build/logs/$target-$(date -u +%Y%m%dT%H%M%SZ).log
mkdir -p "$build/logs"
before=$(ls "$corpus" | wc -l)
started=$(date +%s)
status=0
"$binary" "$found" "$corpus" "${dict[@]}" -max_total_time="$seconds" -runs="$runs" -timeout=20 -print_final_stats=1 \
  -artifact_prefix="$build/crashes/$target-" 2> >(tee "$log" >&2) || status=$?
wait  # for tee
elapsed=$(($(date +%s) - started))
# Edges only (no hit counts): the committed corpus keeps one input per new branch and stays small.
# The merge runs every input again: what fails there is a finding too (a flaky one), kept beside
# the campaign's crashes and recorded with them.
"$binary" -merge=1 -use_counters=0 -artifact_prefix="$build/crashes/$target-merge-" "$corpus" "$found" 2>&1 |
  tee -a "$log" | tail -1
after=$(ls "$corpus" | wc -l)
echo "$corpus: $before -> $after files, $(du -sh --apparent-size "$corpus" | cut -f1)"
# The campaign's record: libFuzzer's own final statistics, never edited by hand.
final_stat() { sed -n "s/^stat::$1: *//p" "$log" | tail -1; }
crash=$(sed -n 's/^artifact_prefix=.*; Test unit written to //p' "$log" | paste -sd' ' -)
record=$root/tests/fuzz/campaigns/$target.tsv
mkdir -p "$(dirname "$record")"
[[ -s $record ]] || printf 'date\tcommit\tsanitizers\tnice\tseconds\texecutions\texec_per_s\tnew_units\tpeak_rss_mb\tcorpus\texit\tcrash\n' >"$record"
printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$(date -u +%Y-%m-%dT%H:%MZ)" "$commit" "$sanitize" "$(nice)" \
  "$elapsed" "$(final_stat number_of_executed_units)" "$(final_stat average_exec_per_sec)" "$(final_stat new_units_added)" \
  "$(final_stat peak_rss_mb)" "$before -> $after" "$status" "${crash:-none}" >>"$record"
echo "recorded in $record"
cat <<MSG
Before committing a corpus that has grown past ~300 files or 1 MB, minimise it (hand-made seeds
have an extension and stay; libFuzzer's finds are bare hashes):
  mkdir $corpus.min && cp $corpus/*.* $corpus.min/
  $binary -merge=1 -use_counters=0 $corpus.min $corpus && rm -r $corpus && mv $corpus.min $corpus
MSG
exit "$status"
