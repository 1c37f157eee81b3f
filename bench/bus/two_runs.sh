#!/usr/bin/env bash
# Two co-simulations started at once on one bus URL (the oscillator, launched participants),
# TRIALS times: counts the trials in which both finished and recorded the same as each other.
# Before sessions were isolated by construction, 8 of 9 such trials had a failed run.
# Usage: bash bench/bus/two_runs.sh [TRIALS] [URL]
set -uo pipefail
cd "$(dirname "$0")/../.."
trials=${1:-10}
url=${2:-udpm://239.255.76.67:7697?ttl=0}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
ok=0
for t in $(seq "$trials"); do
  for k in 1 2; do
    ./build/bin/cosim_master configs/oscillator.yaml --output "$out/$k.h5" --set time.end=0.2 \
      --set output.csv="$out/$k.csv" --set output.progress=off --set "bus.url=$url" 2>"$out/$k.log" &
    eval "pid$k=$!"
  done
  wait "$pid1"; c1=$?
  wait "$pid2"; c2=$?
  if [ $c1 = 0 ] && [ $c2 = 0 ] && cmp -s "$out/1.csv" "$out/2.csv"; then ok=$((ok + 1));
  else echo "trial $t: exit codes $c1 $c2"; tail -2 "$out/1.log" "$out/2.log"; fi
done
echo "two runs at once on $url: $ok of $trials trials had both finish with identical records"
