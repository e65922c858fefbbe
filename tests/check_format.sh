#!/usr/bin/env bash
# Fails when a C++ source of the tree is not formatted as .clang-format says (clang-format's dry
# run; fix with clang-format -i FILE). Usage: tests/check_format.sh CLANG_FORMAT [SOURCE_ROOT]
set -euo pipefail
clang_format=$1
root=${2:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}
cd "$root"
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  mapfile -t files < <(git ls-files --cached --others --exclude-standard -- '*.cpp' '*.hpp')
else
  mapfile -t files < <(find core protocol server clients tests \( -name '*.cpp' -o -name '*.hpp' \))
fi
"$clang_format" --dry-run --Werror "${files[@]}"
echo "format: ${#files[@]} files as .clang-format says"
