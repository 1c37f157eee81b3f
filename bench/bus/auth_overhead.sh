#!/usr/bin/env bash
# What the key costs on the bus (docs/security.md): the oscillator over LCM on loopback (three
# processes, 10,000 macro steps of 5e-4 s), alternately without and with a key, 3 runs each. Prints the
# median round trip per macro step (request sent to reply received, both participants) and the
# run's wall time per step, and their ratios keyed / unkeyed. No assertion: numbers to read.
# Usage: bash bench/bus/auth_overhead.sh [runs]
set -euo pipefail
cd "$(dirname "$0")/../.."
[ -x build/bin/cosim_master ] || bash scripts/build.sh
bash scripts/multicast.sh
runs=${1:-3}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
key=$(./build/bin/cosim_master --new-key "$out/key" 2>/dev/null; cat "$out/key")
run() {  # $1: output file, then the environment changes for `env`
  local file=$1
  shift
  env "$@" ./build/bin/cosim_master configs/oscillator.yaml --output "$file" \
    --set time.end=5 --set time.macro_step=5e-4 --set output.csv= --set output.progress=off \
    --set "bus.url=udpm://239.255.76.67:7691?ttl=0" --set "bus.authenticate=${authenticate:-true}" \
    2> "$file.log" || { cat "$file.log"; exit 1; }
}
for i in $(seq "$runs"); do
  authenticate=false run "$out/plain_$i.h5" -u COSIM_KEY -u COSIM_KEY_FILE
  run "$out/keyed_$i.h5" -u COSIM_KEY_FILE COSIM_KEY="$key"
done
/usr/bin/python3 - "$out" "$runs" <<'PY'
import sys
import h5py
import numpy as np

out, runs = sys.argv[1], int(sys.argv[2])
def stats(kind):
    rt, wall = [], []
    for i in range(1, runs + 1):
        with h5py.File(f"{out}/{kind}_{i}.h5", "r") as f:
            assert f["bus/auth/keyed"][0] == (kind == "keyed"), kind
            wall.append(np.median(f["timing/step_wall"][1:]))
            for p in f["participants"]:
                rt.append(f[f"participants/{p}/timing/round_trip"][1:])
    return np.median(np.concatenate(rt)), np.median(wall)
(rp, wp), (rk, wk) = stats("plain"), stats("keyed")
print(f"round trip median: no key {rp*1e6:.1f} us, key {rk*1e6:.1f} us, ratio {rk/rp:.3f}")
print(f"wall per step median: no key {wp*1e6:.1f} us, key {wk*1e6:.1f} us, ratio {wk/wp:.3f}")
PY
