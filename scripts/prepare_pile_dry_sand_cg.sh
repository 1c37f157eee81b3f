#!/usr/bin/env bash
# Prepares the wheel loader's dry-sand pile at coarser grains (docs/soil_models.md "Coarse
# graining"): the two stages of scripts/prepare_pile_dry_sand.sh with grains S times the radius,
# 10,000 / S^3 of them in the same bay. Stage 1 (configs/soil/pile_dry_sand_prepare.yaml) runs
# with particles.coarse_grain S (radius, count and DEM step scaled, the material otherwise the
# same) and prints the packing fraction, bulk density and coordination; stage 2
# (configs/soil/pile_dry_sand_release.yaml) loads that bed, so its grain radius and step are set
# to the same scaled values (a checkpoint refuses coarse_grain). The settle threshold per grain
# (3e-4 J at 1x) is scaled by S^3: the same grain speed. The packing is measured inside the same
# 0.34 m margin as at 1x (2.5 / S diameters), since the 1.2 m high bed is only 8.7 / S
# diameters high and 2.5 diameters would leave no inner region at S >= 2.
# Writes results/pile_dry_sand_cg<T>.h5, T = S with '.' as 'p' (skipped when it exists).
#   bash scripts/prepare_pile_dry_sand_cg.sh 1.5 [2 3 ...]
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { echo "usage: bash scripts/prepare_pile_dry_sand_cg.sh S [S ...] (grain size factors, e.g. 1.5 2 3)" >&2; exit 2; }
mkdir -p results
for s in "$@"; do
  if ! [[ "$s" =~ ^[0-9]+(\.[0-9]+)?$ ]] || ! awk -v s="$s" 'BEGIN{exit !(s>=1 && s<=5)}'; then
    echo "prepare_pile_dry_sand_cg: '$s' is not a grain size factor in [1, 5] (e.g. 1.5, 2, 3)" >&2
    exit 2
  fi
  t=${s/./p}
  out=results/pile_dry_sand_cg$t.h5
  if [ -f "$out" ]; then
    echo "prepare_pile_dry_sand_cg: $out exists (delete it to prepare again)"
    continue
  fi
  read -r dt rmin rmax ke margin < <(awk -v s="$s" 'BEGIN{printf "%.6g %.6g %.6g %.6g %.6g\n", 1e-4*s, 0.06*s, 0.075*s, 3e-4*s*s*s, 2.5/s}')
  nice ./build/bin/dem_run configs/soil/pile_dry_sand_prepare.yaml \
    --set particles.coarse_grain="$s" --set prepare.ke_per_particle="$ke" \
    --set prepare.margin="$margin" \
    --set prepare.checkpoint="results/pile_dry_sand_cg${t}_bed.h5" \
    --set output.file="results/pile_dry_sand_cg${t}_prepare.h5"
  nice ./build/bin/dem_run configs/soil/pile_dry_sand_release.yaml \
    --set scene.dt="$dt" \
    --set "species.0.radius={distribution: uniform, min: $rmin, max: $rmax}" \
    --set particles.checkpoint="../../results/pile_dry_sand_cg${t}_bed.h5" \
    --set settle.ke_per_particle="$ke" --set settle.checkpoint="$out" \
    --set output.file="results/pile_dry_sand_cg${t}_release.h5"
  echo "prepare_pile_dry_sand_cg: wrote $out"
done
