#!/usr/bin/env bash
# The hauler job: sets up, builds, prepares the soil load in the dump body (once; a granular
# packing of dry sand in two stages, configs/soil/hauler_load_prepare.yaml and
# hauler_load_release.yaml: results/hauler_load.h5, about a minute), runs the hauler
# discharging it (configs/hauler.yaml: cosim_master + hauler_adapter +
# dem_service, 22 s of the tipping profile, a few minutes on 2 cores) and draws the charts:
#   results/hauler.h5, .csv, results/hauler_front_axle.png, _rear_axles.png, _discharge.png,
#   results/hauler_soil.h5 + .xdmf (particles, dump body and walls for ParaView) and
#   results/hauler_soil_last.png (a picture of the last snapshot; docs/visualise.md).
# Extra arguments go to cosim_master, e.g. --set time.end=10
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
bash scripts/multicast.sh
mkdir -p results
if [ ! -f results/hauler_load.h5 ]; then
  echo "run_hauler: preparing the load in the body (once): dem_run configs/soil/hauler_load_prepare.yaml, then hauler_load_release.yaml"
  ./build/bin/dem_run configs/soil/hauler_load_prepare.yaml
  ./build/bin/dem_run configs/soil/hauler_load_release.yaml
fi
./build/bin/cosim_master configs/hauler.yaml "$@"
/usr/bin/python3 master/studies/plot_hauler.py results/hauler.h5
# A picture of the last snapshot (ParaView under xvfb-run, a few seconds); a movie of the whole
# run is `bash scripts/render.sh results/hauler_soil.xdmf` (docs/visualise.md).
bash scripts/render.sh results/hauler_soil.xdmf --out results --last
