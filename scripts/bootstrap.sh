#!/usr/bin/env bash
# Installs every dependency mtlod needs on Debian 12: Debian packages with apt-get, npm packages
# into scripts/node_modules. Idempotent: when everything is there it installs nothing.
#   scripts/bootstrap.sh                    everything: build, tests, benchmarks, browser test
#   scripts/bootstrap.sh --profile build    what building and serving needs (scripts/run.sh, docker/Dockerfile)
#   scripts/bootstrap.sh --profile runtime  only the shared libraries the binaries load (no npm)
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

profile=all
if [ "${1:-}" = "--profile" ]; then profile=${2:-}; fi
case "$profile" in all|build|runtime) ;; *) echo "bootstrap: --profile must be all, build or runtime" >&2; exit 2 ;; esac

build_packages=(
  build-essential cmake ninja-build ccache pkg-config gzip
  libboost-dev libboost-program-options-dev   # Asio and Beast are header-only in libboost-dev
  nlohmann-json3-dev libopenmesh-dev libdraco-dev draco libglm-dev
  libcli11-dev libspdlog-dev libfmt-dev libpng-dev
  libtinygltf-dev                             # .glb output (header-only here: compiled into core/io)
  libmeshoptimizer-dev                        # the evaluation's peer simplifier
  libssl-dev                                  # TLS (Asio's SSL streams) and the access tokens' digests
)
test_packages=(
  libgtest-dev libgmock-dev libbenchmark-dev
  libopencv-dev                               # a peer measured in the benchmarks
  chromium                                    # the browser test drives the viewer headless
  haproxy                                     # the failover test runs replicas behind it
  openssl                                     # the TLS tests make their certificates with it
  clang-format                                # the test suite checks the tree's formatting
  prometheus                                  # its promtool checks the server's /metrics
  # tests/deploy/container_test.sh builds docker/Dockerfile and runs docker/compose.yaml with these:
  podman runc netavark aardvark-dns iptables debootstrap podman-compose curl
)
# What the binaries load at run time (the -dev packages above depend on these).
runtime_packages=(libdraco7 libopenmesh1 libspdlog1.10 libfmt9 libpng16-16 libmeshoptimizer2d libssl3)

case "$profile" in
  all) wanted=("${build_packages[@]}" "${test_packages[@]}") ;;
  build) wanted=("${build_packages[@]}") ;;
  runtime) wanted=("${runtime_packages[@]}") ;;
esac

missing=()
for package in "${wanted[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
if [ "$profile" != runtime ]; then
  # Node.js may come from another Debian-format source; only install Debian's when none is present.
  command -v node >/dev/null 2>&1 || missing+=(nodejs)
  command -v npm >/dev/null 2>&1 || missing+=(npm)
fi

if ((${#missing[@]})); then
  echo "bootstrap: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo=sudo
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  # Containers (the build and runtime profiles) stay small; a developer machine gets the usual set.
  options=()
  [ "$profile" = all ] || options=(--no-install-recommends)
  $sudo apt-get install -y -qq "${options[@]}" "${missing[@]}" >/dev/null
fi
[ "$profile" = runtime ] && exit 0

# npm packages (built-in models; three.js for the viewer; playwright-core drives Chromium in tests; gltf-validator checks the tools' .glb files). --ignore-scripts: the dragon package's build hook is not needed.
if ! (cd "$root/scripts" && npm ls --silent >/dev/null 2>&1); then
  echo "bootstrap: installing npm packages into scripts/node_modules"
  (cd "$root/scripts" && npm ci --ignore-scripts --no-audit --no-fund --loglevel=error)
fi
