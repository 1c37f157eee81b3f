#!/usr/bin/env bash
# The main job: sets up, builds, prepares the soil pile (once: the dry-sand pile,
# results/pile_dry_sand.h5, scripts/prepare_pile_dry_sand.sh, about a minute), runs the wheel
# loader filling its bucket (configs/wheel_loader.yaml: cosim_master + wheel_loader_adapter +
# dem_service, 15 s of maneuver, a few minutes on 2 cores) and draws the charts:
#   results/wheel_loader.h5, .csv, results/wheel_loader_bearing_forces.png, _machine.png,
#   results/wheel_loader_soil.h5 + .xdmf (particles, bucket and walls for ParaView) and
#   results/wheel_loader_soil_last.png (a picture of the last snapshot; docs/visualise.md).
# Extra arguments go to cosim_master, e.g. --set time.macro_step=2e-3 --set time.end=5
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
bash scripts/multicast.sh
mkdir -p results
bash scripts/prepare_pile_dry_sand.sh
./build/bin/cosim_master configs/wheel_loader.yaml "$@"
/usr/bin/python3 master/studies/plot_run.py results/wheel_loader.h5
# A picture of the last snapshot (ParaView under xvfb-run, a few seconds); a movie of the whole
# run is `bash scripts/render.sh results/wheel_loader_soil.xdmf` (docs/visualise.md).
bash scripts/render.sh results/wheel_loader_soil.xdmf --out results --last
