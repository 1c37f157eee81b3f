#!/usr/bin/env bash
# Bus round trip per macro step on loopback: the oscillator over LCM (three processes),
# 10 s at macro step 1e-3 s (10,000 steps). Prints median and p99 of the round trip and of
# its bus part (round trip - participant compute), and the share of wall time on the bus.
# Usage: bash bench/bus/roundtrip.sh [extra cosim_master --set arguments]
set -euo pipefail
cd "$(dirname "$0")/../.."
[ -x build/bin/cosim_master ] || bash scripts/build.sh
bash scripts/multicast.sh
out=$(mktemp -d)
./build/bin/cosim_master configs/oscillator.yaml --output "$out/bench.h5" \
  --set time.end=10 --set time.macro_step=1e-3 --set output.csv= --set output.progress=off \
  --set "bus.url=udpm://239.255.76.67:7690?ttl=0" "$@" 2> "$out/log" || { cat "$out/log"; exit 1; }
/usr/bin/python3 bench/bus/report.py "$out/bench.h5"
rm -rf "$out"
