#!/usr/bin/env bash
# Loss recovery across hosts: the oscillator (configs/oscillator.yaml, 2000 macro steps, both
# halves started by hand) across the three namespaces of tests/netns/rig.sh, through
# netns_relay with the same impairment on every link. Prints the wall time, its ratio to the
# lossless run with the same 1 ms delay (and to the run without any impairment), and the
# resends. Root only.
# Usage: sudo bash bench/bus/netns_loss.sh [REPEATS]   (env SEED: the relay's seed, default 1)
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
bin=$root/build/bin
[ -x "$bin/netns_relay" ] && [ -x "$bin/cosim_master" ] || { echo "build netns_relay, cosim_master and oscillator_participant first"; exit 1; }
reason=$(bash tests/netns/rig.sh check) || { echo "skipped: $reason"; exit 0; }
repeats=${1:-1}
p=bn$$
url='udpm://239.255.76.67:7667?ttl=1'
out=$(mktemp -d)
trap 'bash tests/netns/rig.sh down $p; rm -rf "$out"' EXIT
bash tests/netns/rig.sh up $p

# run TAG SPEC: one co-simulation; prints "wall resends"
run() {
  local tag=$1 spec=$2
  ip netns exec ${p}sw "$bin/netns_relay" --seed "${SEED:-1}" ${p}a1:$spec ${p}b1:$spec ${p}c1:$spec 2>"$out/$tag.relay" &
  local relay=$!
  sleep 0.3
  ip netns exec ${p}b "$bin/oscillator_participant" --side mass1 --bus "$url" --wait 60 2>"$out/$tag.m1" &
  local m1=$!
  ip netns exec ${p}c "$bin/oscillator_participant" --side mass2 --bus "$url" --wait 60 2>"$out/$tag.m2" &
  local m2=$!
  local start end
  start=$(date +%s.%N)
  ip netns exec ${p}a "$bin/cosim_master" configs/oscillator.yaml --output "$out/$tag.h5" --set "bus.url=$url" \
    --set participants.mass1.launch=null --set participants.mass2.launch=null --set bus.authenticate=false --set output.csv= \
    --set output.progress=off 2>"$out/$tag.log" || { echo "run $tag failed:" >&2; tail -3 "$out/$tag.log" >&2; }
  end=$(date +%s.%N)
  wait $m1 $m2 || true
  kill $relay; wait $relay || true
  local resent
  resent=$(sed -n 's/^cosim_master: \([0-9]*\) request(s) resent.*/\1/p' "$out/$tag.log")
  echo "$(echo "$end - $start" | bc) ${resent:-?}"
}

printf "%-44s %8s %8s %8s %8s\n" "impairment on every link" "wall s" "/delay" "/none" "resends"
for r in $(seq "$repeats"); do
  read -r none _ < <(run none "loss=0")
  read -r base _ < <(run base "delay=0.001")
  printf "%-44s %8.2f %8.2f %8.2f %8s\n" "none" "$none" "$(echo "$none / $base" | bc -l)" 1 0
  printf "%-44s %8.2f %8.2f %8.2f %8s\n" "1 ms delay" "$base" 1 "$(echo "$base / $none" | bc -l)" 0
  for loss in 0.05 0.20; do
    read -r wall resent < <(run "l$loss" "loss=$loss,dup=0.01,reorder=0.05,delay=0.001")
    printf "%-44s %8.2f %8.2f %8.2f %8s\n" "$loss loss, 0.01 dup, 0.05 reorder, 1 ms delay" "$wall" \
      "$(echo "$wall / $base" | bc -l)" "$(echo "$wall / $none" | bc -l)" "$resent"
  done
done
