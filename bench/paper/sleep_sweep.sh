#!/usr/bin/env bash
# Speed against accuracy of sleeping thresholds on the paper's scene, in one command: the
# all-active reference, N scatter members (the reference moved by 4 nm, 1e-7 of a radius, with
# their own seeds), one run per threshold (box neighbourhood), then the table and the chart of
# bench/paper/speed_accuracy.py. A benchmark, not a test (docs/performance.md, "Sleeping
# thresholds charted").
#
#   bash bench/paper/sleep_sweep.sh [--thresholds 0.01/25,0.02/100,0.03/70/0.015,0.1/250]
#                                   [--members 2] [--window 0.3] [--out results/sleep_sweep]
#
# A threshold is SPEED/STEPS or SPEED/STEPS/WAKE (m/s / steps / m/s: scene.sleep.speed, steps
# and wake_speed, which defaults to SPEED and may not exceed it); the steps must exceed
# 2 SPEED / (|g| dt). dem_run checks both. Needs the prepared pile (bench/paper/prepare_pile.sh). With the defaults it
# runs 7 maneuvers: about 6 minutes on an idle 2-core machine.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
thresholds="0.01/25,0.02/100,0.03/70/0.015,0.1/250"
members=2
window=0.3
out=results/sleep_sweep
usage() { sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
while [ $# -gt 0 ]; do
  case "$1" in
    --thresholds) thresholds="${2:?--thresholds needs a list like 0.02/100,0.1/250/0.02}"; shift 2 ;;
    --members) members="${2:?--members needs a count}"; shift 2 ;;
    --window) window="${2:?--window needs seconds}"; shift 2 ;;
    --out) out="${2:?--out needs a folder}"; shift 2 ;;
    -h|--help) usage ;;
    *) echo "sleep_sweep: unknown argument '$1'" >&2; usage ;;
  esac
done
if ! [[ "$members" =~ ^[0-9]+$ ]] || [ "$members" -lt 1 ] || [ "$members" -gt 20 ]; then
  echo "sleep_sweep: --members must be a whole number from 1 to 20, got '$members'" >&2; exit 2
fi
IFS=',' read -r -a list <<< "$thresholds"
for t in "${list[@]}"; do
  if ! [[ "$t" =~ ^[0-9]*\.?[0-9]+/[0-9]+(/[0-9]*\.?[0-9]+)?$ ]]; then
    echo "sleep_sweep: threshold '$t' is not SPEED/STEPS or SPEED/STEPS/WAKE (e.g. 0.02/100 or 0.1/250/0.02)" >&2
    exit 2
  fi
done
mkdir -p "$out"
scene() {  # FOLDER, then --set arguments
  local dir="$1"; shift
  echo "sleep_sweep: $(date -u +%H:%M:%S) $dir" >&2
  if ! bash bench/paper/paper_scene.sh --policies needed --window "$window" --out "$dir" "$@" \
      > "$dir.txt" 2>&1; then
    echo "sleep_sweep: the run of $dir failed; its output is in $dir.txt:" >&2
    tail -5 "$dir.txt" >&2
    exit 1
  fi
  grep "whole maneuver" "$dir.txt" >&2 || true
}
scene "$out/reference"
scatter=()
for ((m = 1; m <= members; m++)); do
  scene "$out/member_$m" --set particles.perturb.amplitude=4e-9 --set particles.perturb.seed="$m"
  scatter+=(--scatter "$out/member_$m")
done
runs=()
for t in "${list[@]}"; do
  IFS='/' read -r speed steps wake <<< "$t"
  dir="$out/sleep_${speed}_${steps}"
  wake_set=()
  if [ -n "$wake" ]; then dir="${dir}_wake_$wake"; wake_set=(--set scene.sleep.wake_speed="$wake"); fi
  scene "$dir" --set scene.sleep.enabled=true --set scene.sleep.neighbourhood=box \
    --set scene.sleep.speed="$speed" --set scene.sleep.steps="$steps" "${wake_set[@]+"${wake_set[@]}"}"
  runs+=("$t=$dir")
done
/usr/bin/python3 bench/paper/speed_accuracy.py --reference "$out/reference" "${scatter[@]}" \
  "${runs[@]}" --out "$out/speed_accuracy.png"
