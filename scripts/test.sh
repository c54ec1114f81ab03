#!/usr/bin/env bash
# Installs the dependencies, builds, and runs the whole test suite (the README's test command).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
./scripts/build.sh
ctest --test-dir "${NURBSREG_BUILD_DIR:-build}" --output-on-failure --parallel "$(nproc)" \
  --timeout 600
