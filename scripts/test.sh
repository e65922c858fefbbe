#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds with AddressSanitizer and
# UndefinedBehaviorSanitizer (optimised, with debug info), prepares the built-in models and runs
# every test through ctest.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/scripts/bootstrap.sh"
"$root/scripts/prepare-models.sh"
# Benchmarks are left out here (timing means nothing under sanitizers); BENCHMARKS.md builds them in Release.
"$root/scripts/build.sh" test -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMTLOD_SANITIZE=address,undefined -DMTLOD_BENCHMARKS=OFF
cd "$root/build/test"
ctest --output-on-failure -j "$(nproc)" "$@"
