#!/usr/bin/env bash
# Configures and builds nurbsreg (Release, Ninja, ccache when present) into build/.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir="${NURBSREG_BUILD_DIR:-build}"
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build "$build_dir" --parallel "${NURBSREG_JOBS:-$(nproc)}"
