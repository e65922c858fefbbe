#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds with AddressSanitizer and
# UndefinedBehaviorSanitizer (optimised, with line tables), prepares the built-in models and runs
# every test through ctest.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/scripts/bootstrap.sh"
"$root/scripts/prepare-models.sh"
# Benchmarks are left out here (timing means nothing under sanitizers); BENCHMARKS.md builds them in Release.
# Line tables only (-g1): a sanitizer's report still names every frame's function, file and line,
# and the server's files compile in about 0.6 of the time full debug info takes (BENCHMARKS.md).
"$root/scripts/build.sh" test -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
  -DMTLOD_SANITIZE=address,undefined -DMTLOD_BENCHMARKS=OFF
cd "$root/build/test"
ctest --output-on-failure -j "$(nproc)" "$@"
