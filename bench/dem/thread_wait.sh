#!/usr/bin/env bash
# Single-process cost of each scene.thread_wait policy: dem_side_by_side (the LAMMPS
# side-by-side scenes, docs/performance.md) on the settled 10k and 150k beds, 2 threads, broad
# phase when needed (0) and every 5 steps, policies interleaved within each repeat. Prints
# particle-steps/s per run and the median per policy, and each policy's rate over spin's.
#   bash bench/dem/thread_wait.sh [--repeats 3] [--sizes 10000,150000] [--dir results/bench_lammps]
#                                 [--policies yield,passive,brief,spin] [--work 1e7 particle-steps per run]
# The beds come from `dem_side_by_side prepare --kind bed --n N --dir DIR` (bench/lammps).
set -euo pipefail
cd "$(dirname "$0")/../.."
repeats=3 sizes=10000,150000 dir=results/bench_lammps policies=yield,passive,spin work=10000000
while [ $# -gt 0 ]; do
  case "$1" in
    --repeats) repeats=$2; shift 2 ;;
    --sizes) sizes=$2; shift 2 ;;
    --dir) dir=$2; shift 2 ;;
    --policies) policies=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    *) echo "usage: $0 [--repeats N] [--sizes 10000,150000] [--dir DIR] [--policies ...] [--work N]" >&2; exit 2 ;;
  esac
done
bin=build/bin/dem_side_by_side
[ -x $bin ] || cmake --build build --target dem_side_by_side
IFS=, read -ra ns <<< "$sizes"
IFS=, read -ra pols <<< "$policies"
for n in "${ns[@]}"; do
  [ -f "$dir/bed_$n.h5" ] || $bin prepare --kind bed --n "$n" --dir "$dir"
done
rows=$(mktemp)
trap 'rm -f "$rows"' EXIT
echo "thread_wait: 2 threads, $repeats repeat(s), load average at start $(cut -d' ' -f1-3 /proc/loadavg)"
printf "%-7s %-8s %-8s %-6s %12s %9s %6s\n" n interval policy repeat rate cpu_share load1
for ((r = 1; r <= repeats; r++)); do
  for n in "${ns[@]}"; do
    steps=$((work / n / 5 * 5))
    for iv in 0 5; do
      for p in "${pols[@]}"; do
        line=$(env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT $bin run --kind bed --n "$n" --dir "$dir" \
               --threads 2 --interval $iv --steps $steps --thread-wait "$p" 2>/dev/null | grep '^rate')
        rate=$(echo "$line" | awk '{print $2}') share=$(echo "$line" | awk '{print $10}')
        printf "%-7s %-8s %-8s %-6s %12.4g %9s %6s\n" "$n" "$iv" "$p" "$r" "$rate" "$share" \
               "$(cut -d' ' -f1 /proc/loadavg)"
        echo "$n $iv $p $rate" >> "$rows"
      done
    done
  done
done
echo
echo "median particle-steps/s (and / spin's median):"
/usr/bin/python3 - "$rows" <<'PY'
import statistics, sys
d = {}
for line in open(sys.argv[1]):
    n, iv, p, rate = line.split()
    d.setdefault((int(n), int(iv)), {}).setdefault(p, []).append(float(rate))
for (n, iv), by in sorted(d.items()):
    spin = statistics.median(by["spin"]) if "spin" in by else None
    cells = []
    for p, v in by.items():
        m = statistics.median(v)
        cells.append(f"{p} {m:.3g}" + (f" ({m / spin:.2f})" if spin else ""))
    print(f"n {n:>6} interval {iv}: " + ", ".join(cells))
PY
echo "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)"
