#!/usr/bin/env bash
# Installs Debian's LIGGGHTS (`liggghts`) and Open MPI (`mpirun`) if either is missing, like
# bench/lammps/ensure_lammps.sh. Idempotent; needs root.
set -euo pipefail
missing=()
for p in liggghts openmpi-bin; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "tool_side_by_side: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
command -v liggghts >/dev/null || { echo "tool_side_by_side: liggghts not found after installing liggghts" >&2; exit 1; }
command -v mpirun >/dev/null || { echo "tool_side_by_side: mpirun not found after installing openmpi-bin" >&2; exit 1; }
