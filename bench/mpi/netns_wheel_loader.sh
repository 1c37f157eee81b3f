#!/usr/bin/env bash
# The main job across the namespace rig (not a test; root; docs/mpi.md, "Across hosts"): the
# DEM soil (dem_service) as an MPI job on hosts a and b (rank 0, the bus participant, on a), the
# co-simulation master and the wheel loader it launches on host c, a keyed bus (ttl=1) through
# netns_relay. With --compare, then the same co-simulation with every process on this host (the
# master launching dem_service itself, one rank), and the bucket's wrench of both compared.
#
#   bash bench/mpi/netns_wheel_loader.sh [--np 1] [--end 1.5] [--loss 0] [--compare]
#        [--config configs/wheel_loader.yaml] [--out results/wheel_loader_rig.h5]
#
# --end: the bucket meets the pile at t = 1.23 s (default 1.5 s: 1500 macro steps).
# The soil's config and its --set options are those of participants.soil.launch in --config
# (read from the YAML). Needs the prepared pile (bash scripts/prepare_pile_dry_sand.sh) and a
# build; --np above 1 runs dem_service decomposed under mpirun, rank 0 on the bus (docs/mpi.md).
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
cd "$repo"
np=1 end=1.5 loss=0 compare=0 config=configs/wheel_loader.yaml out=results/wheel_loader_rig.h5 bin=build/bin
bad() { echo "netns_wheel_loader: $*" >&2; exit 2; }
while [ $# -gt 0 ]; do
  case "$1" in
    --np) [ $# -ge 2 ] || bad "--np needs a rank count"; np=$2; shift 2 ;;
    --end) [ $# -ge 2 ] || bad "--end needs seconds"; end=$2; shift 2 ;;
    --loss) [ $# -ge 2 ] || bad "--loss needs a fraction"; loss=$2; shift 2 ;;
    --compare) compare=1; shift ;;
    --config) [ $# -ge 2 ] || bad "--config needs a file"; config=$2; shift 2 ;;
    --out) [ $# -ge 2 ] || bad "--out needs a file"; out=$2; shift 2 ;;
    --bin) [ $# -ge 2 ] || bad "--bin needs a folder"; bin=$2; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
    *) bad "unknown option '$1' (see --help)" ;;
  esac
done
[[ $np =~ ^[1-9][0-9]*$ ]] || bad "--np $np: expected a rank count"
[[ $end =~ ^[0-9]*\.?[0-9]+$ ]] || bad "--end $end: expected seconds"
[ -f "$config" ] || bad "no config '$config'"
for p in cosim_master wheel_loader_adapter dem_service netns_relay; do
  [ -x "$bin/$p" ] || bad "no $bin/$p: build first (bash scripts/build.sh)"
done
[ -f results/pile_dry_sand.h5 ] || bad "no results/pile_dry_sand.h5: bash scripts/prepare_pile_dry_sand.sh prepares it"

# The soil participant's command from the config: participants.soil.launch, ${config_dir}
# replaced; its first word is dem_service.
mapfile -t launch < <(/usr/bin/python3 - "$config" <<'PY'
import os, sys, yaml
path = sys.argv[1]
cfg = yaml.safe_load(open(path))
launch = (cfg.get("participants", {}).get("soil") or {}).get("launch")
if not isinstance(launch, list) or not launch or os.path.basename(str(launch[0])) != "dem_service":
    sys.exit(f"netns_wheel_loader: {path}: participants.soil.launch is not a dem_service command")
for word in launch[1:]:
    print(str(word).replace("${config_dir}", os.path.dirname(os.path.abspath(path))))
PY
)
[ ${#launch[@]} -ge 1 ] || bad "could not read participants.soil.launch from $config"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$bin/cosim_master" --new-key "$work/key" >/dev/null 2>&1
export COSIM_KEY_FILE=$work/key
url='udpm://239.255.76.67:7667?ttl=1'
mkdir -p "$(dirname "$out")"
master="'$PWD/$bin/cosim_master' '$config' --set 'bus.url=$url' --set participants.soil.launch=null \
  --set time.end=$end --set output.csv= --set output.progress=off --output '$out'"
echo "netns_wheel_loader: the DEM on $np rank(s) in hosts a and b, master and wheel loader in host c, to t = $end s" >&2
t0=$(date +%s.%N)
bash bench/mpi/netns_run.sh --hosts 2 --np "$np" --loss "$loss" --bin "$bin" --beside "$master" \
  -- dem_service "${launch[@]}" --set "output.file=$work/soil_rig.h5" --name soil --bus "$url" --wait 120
t1=$(date +%s.%N)
echo "netns_wheel_loader: across the rig: $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') s wall (with the rig's setup), record $out"

[ "$compare" = 1 ] || exit 0
one="$work/one_host.h5"
unset COSIM_KEY_FILE
t0=$(date +%s.%N)
"$bin/cosim_master" "$config" --set time.end="$end" --set output.csv= --set output.progress=off \
  --set "participants.soil.launch=[dem_service, $(printf '"%s", ' "${launch[@]}")--set, output.file=$work/soil_one.h5]" \
  --output "$one" >"$work/one_host.log" 2>&1 || { tail -20 "$work/one_host.log"; bad "the one-host run failed"; }
t1=$(date +%s.%N)
echo "netns_wheel_loader: on one host: $(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.1f", b - a }') s wall"
/usr/bin/python3 - "$out" "$one" <<'PY'
import sys, h5py, numpy as np
a, b = (h5py.File(f, "r") for f in sys.argv[1:3])
key = "participants/soil/outputs/bucket"
wa, wb = a[key][:], b[key][:]
n = min(len(wa), len(wb))
diff = np.abs(wa[:n] - wb[:n]).max(axis=0)
scale = np.abs(wb[:n]).max(axis=0)
print(f"bucket wrench, {n} samples: {'bit-identical' if wa.tobytes() == wb.tobytes() else 'differs'}; "
      f"max |rig - one host| / max |one host| per component: "
      + " ".join(f"{d / s:.2e}" if s > 0 else "-" for d, s in zip(diff, scale)))
PY
