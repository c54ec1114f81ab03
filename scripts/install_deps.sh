#!/usr/bin/env bash
# Installs every build and test dependency of nurbsreg from Debian 12 packages.
# Idempotent: packages already present are left alone. Uses sudo when not root.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config
  libeigen3-dev libtbb-dev libspdlog-dev libfmt-dev
  libpcl-dev libflann-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev
  # `nurbsreg serve` (HTTP) and its tests' and README's client.
  libcpp-httplib-dev curl
  # Peers measured side by side in bench/ (SISL is AGPL: bench only, never linked into the
  # library); OpenCASCADE also reads STEP/IGES.
  libocct-foundation-dev libocct-modeling-data-dev libocct-modeling-algorithms-dev
  libocct-data-exchange-dev libsisl-dev
  # inspect: the PNG and its legend (cairo, DejaVu fonts); npm fetches three.js for the HTML
  # report at build time (inspect/web/package-lock.json); its tests open the report in headless
  # Chromium and read the PLY with Open3D; bench/inspect compares with CloudCompare's C2M.
  libcairo2-dev fonts-dejavu-core chromium cloudcompare
  # The Python package (python/): built for and tested with Debian's /usr/bin/python3; Open3D
  # for the interop tests.
  pybind11-dev python3-dev python3-numpy python3-pytest python3-open3d
  # The sanitizer and fuzzing builds of scripts/test.sh (clang with AddressSanitizer,
  # UndefinedBehaviorSanitizer, ThreadSanitizer and libFuzzer; the main build stays GCC).
  clang libclang-rt-14-dev
)

# Node.js and npm (inspect's build step): Debian's packages, unless a node with npm is already
# installed (e.g. from NodeSource, whose nodejs package bundles npm and conflicts with Debian's).
if ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"
echo "install_deps: installing ${missing[*]}"
$sudo apt-get update -q
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
