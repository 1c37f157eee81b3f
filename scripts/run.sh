#!/usr/bin/env bash
# The main job: sets up, builds, and runs the default co-simulation on this host
# (for now the dual-mass oscillator across three processes: master + two halves).
# Extra arguments go to cosim_master, e.g. --set time.macro_step=1e-3
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
bash scripts/multicast.sh
mkdir -p results
./build/bin/cosim_master configs/oscillator.yaml "$@"
