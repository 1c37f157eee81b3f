#!/usr/bin/env bash
# Tool side-by-side benchmark against LIGGGHTS (not a test; method and results in
# docs/performance.md, "Tool scene against LIGGGHTS").
#
#   bash bench/liggghts/tool_side_by_side.sh [--repeats 3] [--threads 1,2] [--steps 1000]
#                                            [--warmup 100] [--block 100] [--interval 0]
#                                            [--dir results/bench_liggghts]
#                                            [--bed-dir results/bench_lammps]
#
# Installs Debian's liggghts and openmpi-bin if missing (root), builds dem_tool_side_by_side and
# dem_side_by_side, prepares the scene once (the settled 150k bed of the LAMMPS side-by-side,
# made in --bed-dir if missing, about 2 min; a bucket mesh moving through it), then times ours
# against LIGGGHTS and checks the force on the bucket (exit 1 if the codes disagree).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
bash bench/liggghts/ensure_liggghts.sh
build="${BUILD_DIR:-build}"
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
cmake --build "$build" -j2 --target dem_tool_side_by_side dem_side_by_side >/dev/null
exec /usr/bin/python3 bench/liggghts/tool_side_by_side.py --dem "$build/bin/dem_tool_side_by_side" \
  --bed-tool "$build/bin/dem_side_by_side" "$@"
