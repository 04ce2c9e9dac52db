#!/usr/bin/env bash
# Installs mgcloth's Debian dependencies (idempotent, non-interactive) and builds it in Release into build/.
# Usage: scripts/setup.sh [--no-build]
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev libsuitesparse-dev libhypre-dev libopenblas0-openmp libcgal-dev
  nlohmann-json3-dev libcli11-dev libspdlog-dev libfmt-dev libtinyobjloader-dev
  libgtest-dev libbenchmark-dev libpng-dev libosd-dev libtinygltf-dev libcpp-httplib-dev
  python3-matplotlib openmpi-bin libopenmpi-dev
  pybind11-dev python3-dev python3-numpy python3-pytest python3-venv python3-pip python3-setuptools
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "setup: installing ${missing[*]}"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# ---- viewer: `mgcloth view` / `mgcloth render` and their browser test ------------------------------------------
# Debian's Chromium (headless, driven by playwright-core), Node.js, and three.js + playwright-core from the npm
# registry into web/node_modules at the versions of web/package-lock.json; the build copies them into
# build/share/mgcloth, so nothing is fetched when the viewer runs. Before cmake: web/CMakeLists.txt looks for them.
viewer_missing=()
command -v chromium >/dev/null 2>&1 || viewer_missing+=(chromium)
command -v npm >/dev/null 2>&1 || viewer_missing+=(nodejs npm)
if [ ${#viewer_missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  echo "setup: installing ${viewer_missing[*]}"
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${viewer_missing[@]}"
fi
if [ ! -f web/node_modules/.package-lock.json ] || [ web/package-lock.json -nt web/node_modules/.package-lock.json ]; then
  echo "setup: npm ci in web/ (three.js, playwright-core)"
  (cd web && npm ci --no-audit --no-fund --loglevel=error)
fi
# ---- end of viewer ------------------------------------------------------------------------------------------------

if [ "${1:-}" != "--no-build" ]; then
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
  cmake --build build -j "$(nproc)"
fi
