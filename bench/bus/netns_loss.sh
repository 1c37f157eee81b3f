#!/usr/bin/env bash
# Loss recovery across hosts: the oscillator (configs/oscillator.yaml, 2000 macro steps, both
# halves started by hand) across the three namespaces of tests/netns/rig.sh, through
# netns_relay with the same impairment on every link: none (the clean run, the anchor), 5 % and
# 20 % loss, each with 1 % duplication and 5 % reordering. Each row twice: with the protocol's
# redundancy (every request and fresh reply sent twice, the default) and without it
# (COSIM_BUS_COPIES=1 for every process). Prints the wall time, its ratio to the clean run with
# redundancy, the resends, and the frames the relay received from the hosts (the redundancy's
# cost on a clean run). Root only; not in CI.
# Usage: sudo bash bench/bus/netns_loss.sh [REPEATS]   (env SEED: the relay's seed, default 1)
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
bin=$root/build/bin
[ -x "$bin/netns_relay" ] && [ -x "$bin/cosim_master" ] || { echo "build netns_relay, cosim_master and oscillator_adapter first"; exit 1; }
reason=$(bash tests/netns/rig.sh check) || { echo "skipped: $reason"; exit 0; }
repeats=${1:-1}
p=bn$$
url='udpm://239.255.76.67:7667?ttl=1'
out=$(mktemp -d)
trap 'bash tests/netns/rig.sh down $p; rm -rf "$out"' EXIT
bash tests/netns/rig.sh up $p

# run TAG COPIES SPEC: one co-simulation; prints "wall resends frames"
run() {
  local tag=$1 copies=$2 spec=$3
  ip netns exec ${p}sw "$bin/netns_relay" --seed "${SEED:-1}" ${p}a1:$spec ${p}b1:$spec ${p}c1:$spec 2>"$out/$tag.relay" &
  local relay=$!
  sleep 0.3
  COSIM_BUS_COPIES=$copies ip netns exec ${p}b "$bin/oscillator_adapter" --side mass1 --bus "$url" --wait 60 2>"$out/$tag.m1" &
  local m1=$!
  COSIM_BUS_COPIES=$copies ip netns exec ${p}c "$bin/oscillator_adapter" --side mass2 --bus "$url" --wait 60 2>"$out/$tag.m2" &
  local m2=$!
  local start end
  start=$(date +%s.%N)
  COSIM_BUS_COPIES=$copies ip netns exec ${p}a "$bin/cosim_master" configs/oscillator.yaml --output "$out/$tag.h5" \
    --set "bus.url=$url" --set participants.mass1.launch=null --set participants.mass2.launch=null \
    --set bus.authenticate=false --set output.csv= --set output.progress=off 2>"$out/$tag.log" \
    || { echo "run $tag failed:" >&2; tail -3 "$out/$tag.log" >&2; }
  end=$(date +%s.%N)
  wait $m1 $m2 || true
  kill $relay; wait $relay || true
  local resent frames
  resent=$(sed -n 's/^cosim_master: \([0-9]*\) request(s) resent.*/\1/p' "$out/$tag.log")
  frames=$(sed -n 's/.*: received \([0-9]*\),.*/\1/p' "$out/$tag.relay" | paste -sd+ | bc)
  echo "$(echo "$end - $start" | bc) ${resent:-?} ${frames:-?}"
}

printf "%-36s %-12s %8s %8s %8s %8s\n" "impairment on every link" "redundancy" "wall s" "/clean" "resends" "frames"
for r in $(seq "$repeats"); do
  read -r clean resent frames < <(run clean2 2 "loss=0")
  printf "%-36s %-12s %8.2f %8.2f %8s %8s\n" "none (clean)" "2 copies" "$clean" 1 "$resent" "$frames"
  read -r wall resent frames < <(run clean1 1 "loss=0")
  printf "%-36s %-12s %8.2f %8.2f %8s %8s\n" "none (clean)" "off" "$wall" "$(echo "$wall / $clean" | bc -l)" "$resent" "$frames"
  for loss in 0.05 0.20; do
    for copies in 2 1; do
      read -r wall resent frames < <(run "l$loss-$copies" $copies "loss=$loss,dup=0.01,reorder=0.05")
      printf "%-36s %-12s %8.2f %8.2f %8s %8s\n" "$loss loss, 0.01 dup, 0.05 reorder" \
        "$([ $copies = 2 ] && echo "2 copies" || echo off)" "$wall" "$(echo "$wall / $clean" | bc -l)" "$resent" "$frames"
    done
  done
done
