#!/usr/bin/env bash
# Prepares the main job's pile in dry sand (configs/materials/dry_sand.yaml) in two stages:
# random insertion and deposition into the bay closed by a front wall
# (configs/soil/pile_dry_sand_prepare.yaml: prints packing fraction, bulk density and
# coordination), then the front opened and settled (configs/soil/pile_dry_sand_release.yaml).
# Writes results/pile_dry_sand.h5 and, beside it, results/pile_dry_sand.material: a copy of the
# material file it was prepared with. Skipped when both exist and the material is unchanged; a
# changed material (a new calibration) prepares the pile again, since a pile must be settled with
# the law it is run with. scripts/run.sh calls this.
#   bash scripts/prepare_pile_dry_sand.sh
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p results
material=configs/materials/dry_sand.yaml
stamp=results/pile_dry_sand.material
if [ -f results/pile_dry_sand.h5 ]; then
  if [ -f "$stamp" ] && cmp -s "$stamp" "$material"; then
    echo "prepare_pile_dry_sand: results/pile_dry_sand.h5 exists, prepared with today's $material (delete it to prepare again)"
    exit 0
  fi
  if [ -f "$stamp" ]; then
    echo "prepare_pile_dry_sand: $material changed since results/pile_dry_sand.h5 was prepared: preparing it again"
  else
    echo "prepare_pile_dry_sand: results/pile_dry_sand.h5 has no record of its material ($stamp): preparing it again"
  fi
fi
rm -f "$stamp" results/pile_dry_sand.h5
./build/bin/dem_run configs/soil/pile_dry_sand_prepare.yaml
./build/bin/dem_run configs/soil/pile_dry_sand_release.yaml
cp "$material" "$stamp"
echo "prepare_pile_dry_sand: wrote results/pile_dry_sand.h5"
