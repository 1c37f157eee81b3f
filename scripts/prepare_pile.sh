#!/usr/bin/env bash
# Prepares a variant of the lattice pile (configs/soil/pile_prepare.yaml: the main job's pile
# before issue 43, the scene of docs/wheel_loader_studies.md) once, for studies
# that change the soil (contact stiffness, friction, grain size): a pile must be settled with the
# contact law it is run with, or it starts by slumping or springing up.
#   bash scripts/prepare_pile.sh NAME [dotted.key=value ...]
# writes results/piles/NAME.h5 (skipped when it exists; delete it to prepare again). The keys
# are those of pile_prepare.yaml (docs/dem.md), e.g.
#   bash scripts/prepare_pile.sh mu0.3 contact.particle_particle.friction=0.3
# A study then loads it with participants.soil.parameters.particles.checkpoint:
# ../../results/piles/NAME.h5 (relative to configs/soil/) and the same contact keys.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 1 ]; then
  echo "usage: bash scripts/prepare_pile.sh NAME [dotted.key=value ...]" >&2
  exit 2
fi
name="$1"
shift
if ! [[ "$name" =~ ^[A-Za-z0-9._-]+$ ]]; then
  echo "prepare_pile: NAME '$name' must be letters, digits, '.', '_' or '-' (it names a file)" >&2
  exit 2
fi
mkdir -p results/piles
out="results/piles/$name.h5"
if [ -f "$out" ]; then
  echo "prepare_pile: $out exists (delete it to prepare again)"
  exit 0
fi
sets=()
for kv in "$@"; do
  case "$kv" in
    *=*) sets+=(--set "$kv") ;;
    *) echo "prepare_pile: '$kv' is not dotted.key=value" >&2; exit 2 ;;
  esac
done
tmp="results/piles/$name.tmp.h5"
./build/bin/dem_run configs/soil/pile_prepare.yaml "${sets[@]}" \
  --set "settle.checkpoint=$tmp" --set "output.file=results/piles/${name}_prepare.h5"
mv "$tmp" "$out"
echo "prepare_pile: wrote $out"
