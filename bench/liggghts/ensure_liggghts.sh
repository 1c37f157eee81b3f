#!/usr/bin/env bash
# Installs Debian's LIGGGHTS (`liggghts`) and Open MPI (`mpirun`) if either is missing. Needs root.
set -euo pipefail
bash "$(dirname "${BASH_SOURCE[0]}")/../common/ensure_debian.sh" tool_side_by_side liggghts:liggghts openmpi-bin:mpirun
