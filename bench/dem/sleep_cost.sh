#!/usr/bin/env bash
# Cost of a DEM step on the wheel-loader pile (10k spheres, 1 thread, bucket parked away from
# the pile) with every particle awake and with sleeping enabled (everything falls asleep within
# the first scene.sleep.steps steps): CPU seconds of the process (/usr/bin/time, which a shared
# machine inflates less than wall time) and dem_run's timing table per section.
# Usage: bash bench/dem/sleep_cost.sh [simulated seconds, default 0.3]
# The start-up (loading the pile and the mesh) is measured alone and taken off.
set -euo pipefail
cd "$(dirname "$0")/../.."
dur=${1:-0.3}
[ -f results/pile_small.h5 ] || ./build/bin/dem_run configs/soil/pile_prepare.yaml
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
export OMP_WAIT_POLICY=PASSIVE
for mode in startup active sleep; do
  args=(--set run.duration=$dur --output "$out/$mode.h5")
  [ $mode = startup ] && args=(--set run.duration=0 --output "$out/$mode.h5")
  [ $mode = sleep ] && args+=(--set 'scene.sleep={enabled: true, speed: 0.02, steps: 200, tool_distance: 0.5}')
  /usr/bin/time -o "$out/$mode.cpu" -f "%U %S" nice -n 19 ./build/bin/dem_run bench/dem/sleep_cost.yaml \
    "${args[@]}" > "$out/$mode.txt" 2> "$out/$mode.err"
  read -r u s < "$out/$mode.cpu"
  cpu=$(echo "$u + $s" | bc)
  [ $mode = startup ] && { startup=$cpu; echo "== start-up (load pile and mesh, no step): CPU $cpu s"; continue; }
  steps=$(sed -n 's/^Loop time of .* for \([0-9]*\) steps.*/\1/p' "$out/$mode.txt")
  echo "== $mode: CPU $cpu s, $(echo "scale=3; ($cpu - $startup) * 1000 / $steps" | bc) CPU ms per step after start-up"
  sed -n '/^Loop time/,$p' "$out/$mode.txt"
done
