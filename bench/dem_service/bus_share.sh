#!/usr/bin/env bash
# Share of wall time spent on the bus and in the master, for dem_service with a 150k-particle
# bed at macro steps 2e-3, 1e-3, 5e-4 s (DEM dt 1e-4 s). Goal (design.md): under 5 %.
# Usage: bash bench/dem_service/bus_share.sh [simulated seconds per run, default 0.06]
set -euo pipefail
cd "$(dirname "$0")/../.."
end=${1:-0.06}
[ -x build/bin/cosim_master ] && [ -x build/bin/dem_service ] || bash scripts/build.sh
bash scripts/multicast.sh
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for H in 2e-3 1e-3 5e-4; do
  echo "== macro step $H s, $end s simulated"
  ./build/bin/cosim_master bench/dem_service/cosim.yaml --output "$out/H$H.h5" \
    --set time.macro_step=$H --set time.end=$end \
    --set "bus.url=udpm://239.255.76.67:7691?ttl=0" 2> "$out/log" || { cat "$out/log"; exit 1; }
  grep -E "finished after" "$out/log" || true
  /usr/bin/python3 bench/dem_service/share.py "$out/H$H.h5"
done
