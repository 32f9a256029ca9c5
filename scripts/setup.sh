#!/usr/bin/env bash
# Installs every dependency from Debian packages (idempotent, non-interactive),
# then configures and builds flysfm in build/ (Release).
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake pkg-config ninja-build
  # links the ~100 test executables several times faster than GNU ld
  mold
  libeigen3-dev
  libceres-dev libsuitesparse-dev
  libopencv-dev
  nlohmann-json3-dev
  catch2 libcli11-dev libcpp-httplib-dev libcurl4-openssl-dev
  libopenblas-serial-dev libexif-dev
  libwebsocketpp-dev
  # the coverage surface's Delaunay triangulation (docs/quality.md)
  libcgal-dev
  # the live view (docs/view.md): the three.js it serves, the browser its test drives
  libjs-three chromium
  colmap
  clang libclang-rt-14-dev
)

missing=()
for package in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" \
    || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq \
    --no-install-recommends "${missing[@]}"
fi

if [ ! -f build/CMakeCache.txt ]; then
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
fi
cmake --build build -j"$(nproc)"
