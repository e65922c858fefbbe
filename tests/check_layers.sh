#!/usr/bin/env bash
# Fails when an include points the wrong way between the source folders (README, "Layout"):
#   core/<room>/             core/result.hpp and the rooms below it: util model codec cut view eval
#                            io build threads (core/ARCHITECTURE.md §5)
#   protocol/                core/'s request path (util to view) and protocol/; nlohmann-json, not
#                            CLI11/Boost/spdlog
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

# core/'s rooms, bottom to top (core/CMakeLists.txt): each may include core/result.hpp and the rooms
# up to itself. Only io/ reads meshes with OpenMesh, PNG or tinygltf, and writes glTF's JSON with
# nlohmann-json (tinygltf's own JSON library) where tinygltf cannot.
rooms=(util model codec cut view eval io build threads)
below=''
for room in "${rooms[@]}"; do
  below="${below:+$below|}$room"
  ban='boost/|CLI/|spdlog/'
  [ "$room" = io ] || ban="$ban|nlohmann/|OpenMesh/|png.h|tiny_gltf"
  check "core/$room" "^core/(result\.hpp|($below)/.+)$" "$ban"
done
check core '^core/result\.hpp$' 'boost/|CLI/|spdlog/|nlohmann/|OpenMesh/' -maxdepth 1
request_path='core/(result\.hpp|(util|model|codec|cut|view)/.+)'
check protocol "^($request_path|protocol/.+)$" 'boost/|CLI/|spdlog/|OpenMesh/'
server_allowed='^(core/(result\.hpp|(util|model|codec|cut|view|io|build|threads)/.+)|protocol/.+|server/.+)$'
check server "$server_allowed" 'CLI/' -not -name main.cpp
check server "$server_allowed" '' -name main.cpp  # the program parses its command line
check clients '^(core/.+|protocol/.+|clients/.+)$' ''

[ "$status" = 0 ] && echo "layers: every include points one way"
exit "$status"
