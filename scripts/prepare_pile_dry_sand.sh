#!/usr/bin/env bash
# Prepares the wheel loader's pile in dry sand (configs/materials/dry_sand.yaml) in two stages:
# random insertion and deposition into the bay closed by a front wall
# (configs/soil/pile_dry_sand_prepare.yaml: prints packing fraction, bulk density and
# coordination), then the front opened and settled (configs/soil/pile_dry_sand_release.yaml).
# Writes results/pile_dry_sand.h5 (skipped when it exists; delete it to prepare again).
#   bash scripts/prepare_pile_dry_sand.sh
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p results
if [ -f results/pile_dry_sand.h5 ]; then
  echo "prepare_pile_dry_sand: results/pile_dry_sand.h5 exists (delete it to prepare again)"
  exit 0
fi
./build/bin/dem_run configs/soil/pile_dry_sand_prepare.yaml
./build/bin/dem_run configs/soil/pile_dry_sand_release.yaml
echo "prepare_pile_dry_sand: wrote results/pile_dry_sand.h5"
