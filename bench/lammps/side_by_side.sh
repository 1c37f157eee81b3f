#!/usr/bin/env bash
# Side-by-side benchmark against LAMMPS (not a test; method and results in docs/performance.md).
#
#   bash bench/lammps/side_by_side.sh [--sizes 10k,150k] [--repeats 3] [--threads 1,2]
#                                     [--gas-timing] [--skip-check] [--steps S | --work W]
#                                     [--dir results/bench_lammps]
#   bash bench/lammps/side_by_side.sh --cost-ratio --sizes 10k,1.2M [--repeats 5]
#
# Installs Debian's lammps and openmpi-bin if `lmp` or `mpirun` is missing (root), builds
# dem_side_by_side, checks that both codes agree on a 10k gas (fails loudly if not), then times
# settled beds (600k and 1.2M with --sizes 10k,150k,600k,1.2M). Scenes are cached in --dir.
# --cost-ratio times only ours, 1 thread, the smallest and largest size in turn, and prints the
# cost per particle-step of the large bed against the small one per round (issue 10: <= 1.3x).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
bash bench/lammps/ensure_lammps.sh
build="${BUILD_DIR:-build}"
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
cmake --build "$build" -j2 --target dem_side_by_side >/dev/null
exec /usr/bin/python3 bench/lammps/side_by_side.py --dem "$build/bin/dem_side_by_side" "$@"
