#!/usr/bin/env bash
# Installs Debian's LAMMPS (`lmp`) and Open MPI (`mpirun`) if either is missing. Needs root.
set -euo pipefail
bash "$(dirname "${BASH_SOURCE[0]}")/../common/ensure_debian.sh" side_by_side lammps:lmp openmpi-bin:mpirun
