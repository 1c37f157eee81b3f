#!/usr/bin/env bash
# Sets everything up on a fresh Debian 12 machine, builds, and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
bash scripts/multicast.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
