#!/usr/bin/env bash
# Fails when an include points the wrong way between the source folders (README, "Layout"):
#   core/ (algorithms)       core/ only (not its io/, eval/ or threads/)
#   core/io, eval, threads   core/, and io/ may use eval/ (debug images)
#   protocol/                core/ algorithms and protocol/; nlohmann-json, not CLI11/Boost/spdlog
#   server/                  core/ (not eval/), protocol/, server/
#   clients/                 core/, protocol/, clients/ (not server/)
# Usage: tests/check_layers.sh [SOURCE_ROOT]
set -euo pipefail
root=${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}
cd "$root"
status=0

# check FOLDER ALLOWED-REGEX LIBRARY-BAN [FIND-OPTIONS...]: every include of our folders in FOLDER's
# sources must match ALLOWED-REGEX, and none may include a library matching LIBRARY-BAN.
check() {
  local folder=$1 allowed=$2 library_ban=$3
  shift 3
  while IFS= read -r -d '' file; do
    while IFS= read -r line; do
      local target=${line#*\"}
      target=${target%%\"*}
      case "$target" in core/* | protocol/* | server/* | clients/* | tests/*) ;; *) continue ;; esac
      if ! [[ "$target" =~ $allowed ]]; then
        echo "$file: includes \"$target\" ($folder may include only ${allowed})"
        status=1
      fi
    done < <(grep -E '^\s*#\s*include\s+"' "$file" || true)
    if [ -n "$library_ban" ] && grep -nE "^\s*#\s*include\s+[<\"]($library_ban)" "$file"; then
      echo "$file: ^ a library $folder must not use"
      status=1
    fi
  done < <(find "$folder" "$@" \( -name '*.cpp' -o -name '*.hpp' \) -print0)
}

core_algorithms='^core/[^/]+$'
check core "$core_algorithms" 'boost/|CLI/|spdlog/|nlohmann/|OpenMesh/' -maxdepth 1
check core/io '^core/([^/]+|io/.+|eval/.+)$' 'boost/|CLI/|spdlog/|nlohmann/'
check core/eval '^core/([^/]+|eval/.+)$' 'boost/|CLI/|spdlog/|nlohmann/|OpenMesh/'
check core/threads "$core_algorithms" 'boost/|CLI/|spdlog/|nlohmann/|OpenMesh/'
check protocol '^(core/[^/]+|protocol/.+)$' 'boost/|CLI/|spdlog/|OpenMesh/'
server_allowed='^(core/([^/]+|io/.+|threads/.+)|protocol/.+|server/.+)$'
check server "$server_allowed" 'CLI/' -not -name main.cpp
check server "$server_allowed" '' -name main.cpp  # the program parses its command line
check clients '^(core/.+|protocol/.+|clients/.+)$' ''

[ "$status" = 0 ] && echo "layers: every include points one way"
exit "$status"
