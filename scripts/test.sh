#!/usr/bin/env bash
# Sets everything up on a fresh Debian 12 machine, builds, runs every test, then the fuzz smoke
# run (scripts/fuzz.sh: a separate clang build in build-fuzz/, a few minutes).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
bash scripts/multicast.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
bash scripts/fuzz.sh smoke
