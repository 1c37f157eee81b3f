#!/usr/bin/env bash
# Prepares the paper-sized pile (results/pile_paper.h5) in two stages: a frictionless, dense
# drop into the closed bay (configs/soil/pile_paper_compact.yaml -> results/pile_paper_compact.h5,
# skipped when that file exists), then friction on and the front opened until at rest
# (configs/soil/pile_paper_prepare.yaml). Fails if stage 2 does not reach its rest criterion.
#   nice -n 19 bash bench/paper/prepare_pile.sh
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build}"
mkdir -p results
if [ ! -f results/pile_paper_compact.h5 ]; then
  "$build/bin/dem_run" configs/soil/pile_paper_compact.yaml 2>&1 | tee results/pile_paper_compact.log
fi
"$build/bin/dem_run" configs/soil/pile_paper_prepare.yaml 2>&1 | tee results/pile_paper_prepare.log
if ! grep -q "^settle: at rest" results/pile_paper_prepare.log; then
  echo "prepare_pile: the pile did NOT reach its rest criterion; see results/pile_paper_prepare.log" >&2
  rm -f results/pile_paper.h5
  exit 3
fi
