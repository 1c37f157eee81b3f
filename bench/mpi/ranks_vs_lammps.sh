#!/usr/bin/env bash
# Ours on 2 MPI ranks against LAMMPS on 2 ranks on the LAMMPS side-by-side's settled bed, in the
# same run (issue 48: "still 2x"), with ours on 1 rank x 2 threads as the anchor; per rebuild
# policy, REPEATS rounds interleaved. Not a test: a benchmark (docs/mpi.md, docs/performance.md).
#
#   bash bench/mpi/ranks_vs_lammps.sh [--n 150000] [--steps 500] [--repeats 3] [--policies 5,0]
#                                     [--dir results/bench_lammps]
#
# Installs Debian's lammps and openmpi-bin when missing (bench/lammps/ensure_lammps.sh, root);
# makes the bed with bench/lammps/side_by_side.sh when <dir>/bed_<n>.h5 is missing.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
bash bench/lammps/ensure_lammps.sh
bin=${BUILD_DIR:-build}/bin
[ -x "$bin/dem_run" ] || { echo "ranks_vs_lammps.sh: $bin/dem_run missing: cmake --build build --target dem_run" >&2; exit 2; }
n=150000 dir=results/bench_lammps
args=("$@")
while [ $# -gt 0 ]; do
  case "$1" in
    --n) n=${2:?--n needs a value}; shift 2;;
    --dir) dir=${2:?--dir needs a value}; shift 2;;
    *) shift;;
  esac
done
if [ ! -f "$dir/bed_$n.h5" ]; then
  echo "making the bed $dir/bed_$n.h5 (bench/lammps/side_by_side.sh) ..."
  bash bench/lammps/side_by_side.sh --sizes "$((n / 1000))k" --repeats 1 --skip-check --threads 1 --dir "$dir" >/dev/null
fi
exec /usr/bin/python3 bench/mpi/ranks_vs_lammps.py --dem "$bin/dem_run" "${args[@]}"
