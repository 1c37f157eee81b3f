#!/usr/bin/env bash
# Installs Debian's LAMMPS (`lmp`) and Open MPI (`mpirun`) if either is missing, like
# scripts/setup.sh does for the build packages. Idempotent; needs root.
set -euo pipefail
missing=()
for p in lammps openmpi-bin; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "side_by_side: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
command -v lmp >/dev/null || { echo "side_by_side: lmp not found after installing lammps" >&2; exit 1; }
command -v mpirun >/dev/null || { echo "side_by_side: mpirun not found after installing openmpi-bin" >&2; exit 1; }
