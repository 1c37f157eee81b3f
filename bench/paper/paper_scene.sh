#!/usr/bin/env bash
# The paper's scene as a benchmark (not a test; method and results in docs/performance.md,
# "The paper's scene"):
#
#   nice -n 19 bash bench/paper/paper_scene.sh [--window 0.3] [--policies every5,needed]
#                                              [--threads 2] [--prepare] [--set KEY=VALUE ...]
#
# Drives the 40,662-triangle bucket through the settled 150,000-sphere pile (results/pile_paper.h5)
# along a prescribed maneuver in three phases (penetration, tilt, lift; --window simulated seconds
# each), once with the broad phase every 5 steps and once rebuilt only when needed, and prints per
# phase the simulated and wall time, real-time factor, broad-phase share, rebuilds and peak memory.
# Without the pile it stops and says how to prepare it; --prepare prepares it first (stage 1
# took 26 minutes on shared cores; bench/paper/prepare_pile.sh). Outputs go to results/paper_bench/.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build}"
prepare=0
own_pile=0  # --pile FILE: paper_scene.py checks that file; else the default pile must be there
args=()
for a in "$@"; do
  case "$a" in --pile | --pile=*) own_pile=1 ;; esac
  if [ "$a" = "--prepare" ]; then prepare=1; else args+=("$a"); fi
done
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
cmake --build "$build" -j2 --target dem_run wheel_loader_meshes >/dev/null
if [ "$own_pile" = 0 ] && [ ! -f results/pile_paper.h5 ]; then
  if [ "$prepare" = 1 ]; then
    bash bench/paper/prepare_pile.sh
  else
    echo "paper_scene: results/pile_paper.h5 (the settled paper-sized pile) is missing." >&2
    echo "  Prepare it once (two stages; stage 1 alone took 26 minutes on the shared 2 cores):" >&2
    echo "    nice -n 19 bash bench/paper/prepare_pile.sh" >&2
    echo "  or rerun this command with --prepare." >&2
    exit 2
  fi
fi
exec /usr/bin/python3 bench/paper/paper_scene.py --dem-run "$build/bin/dem_run" "${args[@]+"${args[@]}"}"
