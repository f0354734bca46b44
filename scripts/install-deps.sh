#!/usr/bin/env bash
# Installs every build, test and run-time dependency of tinstream from Debian 12 packages.
# Idempotent: does nothing when everything is already installed. No prompts.
#   scripts/install-deps.sh            build + test dependencies (what `make test` needs)
#   scripts/install-deps.sh --bench    also the benchmark peers (wrk, nginx, Node.js for delatin)
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config git lld   # lld: the linker (CMake)
  libboost-dev                     # Beast/Asio (header-only, 1.74; CGAL needs this one)
  libgeographiclib-dev libproj-dev proj-data libgdal-dev gdal-bin
  libssl-dev                       # libcrypto: sha256 of decoded LAZ records (las-info, tests)
  libsqlite3-dev sqlite3 zlib1g-dev libdeflate-dev libspdlog-dev libfmt-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcgal-dev libgmp-dev libmpfr-dev    # test/benchmark peer only
  libglfw3-dev libepoxy-dev libglm-dev libpng-dev libosmesa6-dev libegl-dev libgl-dev
  libimgui-dev                     # the viewer's window panel (client/CMakeLists.txt)
  clang clang-format clang-tidy curl   # clang: the libFuzzer build (scripts/fuzz.sh)
  libjpeg-dev libwebp-dev          # imagery tiles (JPEG, WebP; PNG through libpng-dev)
  wrk python3                      # the server's abuse/load test (ctest Server.Abuse)
  xvfb                             # xvfb-run: the viewer's window-mode test (Viewer.WindowMode…)
)
# The browser viewers and their tests: Node.js + npm build web/ (web/build.mjs: CesiumJS and
# MapLibre GL JS from npm) and drive Debian's Chromium through playwright-core (tests/web).
# Debian's nodejs + npm unless a Node.js with npm is already installed (e.g. NodeSource's nodejs,
# which bundles npm and conflicts with Debian's npm package).
packages+=(chromium)
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi
if [[ ${1:-} == --bench ]]; then
  packages+=(nginx time)  # (Node.js for the delatin peer: above; wrk: above)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
echo "install-deps: installing ${missing[*]}"
# apt lists may be absent on a fresh machine; update when any package is unknown to apt.
if ! apt-cache show "${missing[@]}" >/dev/null 2>&1; then
  $SUDO apt-get update -qq
fi
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
