#!/usr/bin/env bash
# Installs every dependency mtlod needs on Debian 12: Debian packages with apt-get, npm packages
# into scripts/node_modules. Idempotent: when everything is there it installs nothing.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

debian_packages=(
  build-essential cmake ccache pkg-config gzip
  libboost-dev libboost-program-options-dev   # Asio and Beast are header-only in libboost-dev
  nlohmann-json3-dev libopenmesh-dev libdraco-dev draco libglm-dev
  libcli11-dev libspdlog-dev libfmt-dev libpng-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libmeshoptimizer-dev libopencv-dev          # peers measured in the benchmarks
  chromium                                    # the browser test drives the viewer headless
)

missing=()
for package in "${debian_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
# Node.js may come from another Debian-format source; only install Debian's when none is present.
command -v node >/dev/null 2>&1 || missing+=(nodejs)
command -v npm >/dev/null 2>&1 || missing+=(npm)

if ((${#missing[@]})); then
  echo "bootstrap: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo=sudo
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# npm packages (built-in models; three.js for the viewer; playwright-core drives Chromium in tests). --ignore-scripts: the dragon package's build hook is not needed.
if ! (cd "$root/scripts" && npm ls --silent >/dev/null 2>&1); then
  echo "bootstrap: installing npm packages into scripts/node_modules"
  (cd "$root/scripts" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error)
fi
