#!/usr/bin/env bash
# 2 MPI ranks x 1 thread against 1 rank x 2 threads on the 20k, 150k or 600k bed (issue 48's goal: 0.9x
# or better), interleaved, per broad-phase policy (every 5 steps at skin 0.5; when needed at skin
# 0.3), REPEATS rounds. Prints each run's loop time, the ratio of the medians (1x2 / 2x1: above
# 1 means the ranks are faster) and rank 0's halo line. Not a test: a benchmark (docs/mpi.md).
#
#   bash bench/mpi/ranks_vs_threads.sh [--size 20k|150k|600k] [--steps N] [REPEATS]
#   (default 20k, 500 steps, 3 rounds; from anywhere). LAMMPS at 2 ranks on the side-by-side's
#   bed in the same run: bench/mpi/ranks_vs_lammps.sh.
set -euo pipefail
cd "$(dirname "$0")/../.."
size=20k
steps=500
if [ "${1:-}" = --size ]; then size=${2:-}; shift 2 || true; fi
if [ "${1:-}" = --steps ]; then steps=${2:-}; shift 2 || true; fi
case "$steps" in ''|*[!0-9]*|0) echo "ranks_vs_threads.sh: --steps must be a whole number above 0, got '$steps'" >&2; exit 2;; esac
case "$size" in 20k|150k|600k) ;; *) echo "ranks_vs_threads.sh: --size must be 20k, 150k or 600k, got '$size'" >&2; exit 2;; esac
repeats=${1:-3}
case "$repeats" in ''|*[!0-9]*) echo "ranks_vs_threads.sh: REPEATS must be a whole number, got '$repeats'" >&2; exit 2;; esac
[ "$repeats" -ge 1 ] || { echo "ranks_vs_threads.sh: REPEATS must be at least 1" >&2; exit 2; }
bin=${BUILD_DIR:-build}/bin
for p in dem_run; do [ -x "$bin/$p" ] || { echo "ranks_vs_threads.sh: $bin/$p missing: cmake --build build --target $p" >&2; exit 2; }; done
command -v mpirun >/dev/null || { echo "ranks_vs_threads.sh: mpirun missing: bash scripts/setup.sh installs openmpi-bin" >&2; exit 2; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
mkdir -p results
if [ ! -f results/mpi_bed${size}.h5 ]; then
  echo "making the bed (results/mpi_bed${size}.h5) ..."
  "$bin/dem_run" bench/mpi/bed${size}_prepare.yaml > results/mpi_bed${size}_prepare.log 2>&1
fi
loop() { sed -n 's/^Loop time of \([0-9.]*\) s.*/\1/p' "$1"; }
median() { sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
for policy in "every5:scene.broad_phase_interval=5 scene.skin=0.5" "needed:scene.broad_phase_interval=1000000 scene.skin=0.3"; do
  name=${policy%%:*}; sets=()
  for s in ${policy#*:} "run.duration=$(awk -v n="$steps" 'BEGIN {printf "%.10g", n * 1e-5}')"; do sets+=(--set "$s"); done
  one=(); two=()
  for r in $(seq 1 "$repeats"); do
    "$bin/dem_run" bench/mpi/bed${size}.yaml "${sets[@]}" --set scene.threads=2 \
      --set output.file=results/mpi_bed${size}_1x2.h5 > results/mpi_bed${size}_1x2.log 2>&1
    one+=("$(loop results/mpi_bed${size}_1x2.log)")
    mpirun --oversubscribe -np 2 "$bin/dem_run" bench/mpi/bed${size}.yaml "${sets[@]}" --set scene.threads=1 \
      --set output.file=results/mpi_bed${size}_2x1.h5 > results/mpi_bed${size}_2x1.log 2>&1
    two+=("$(loop results/mpi_bed${size}_2x1.log)")
    echo "$name round $r: 1 rank x 2 threads ${one[-1]} s, 2 ranks x 1 thread ${two[-1]} s ($steps steps, $size)"
  done
  m1=$(printf '%s\n' "${one[@]}" | median); m2=$(printf '%s\n' "${two[@]}" | median)
  echo "$name: medians $m1 s and $m2 s: 2 ranks x 1 thread at $(awk -v a="$m1" -v b="$m2" 'BEGIN {printf "%.2f", a / b}')x the speed of 1 rank x 2 threads (goal 0.9)"
  grep "rank 0" results/mpi_bed${size}_2x1.log | sed 's/^ */  /'
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
