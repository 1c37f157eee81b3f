#!/usr/bin/env bash
# mpi_netns_test: mpi_probe as 3 ranks on the rig's three namespaced hosts (tests/netns/rig.sh),
# started by mpirun in host a through scripts/mpi_netns_agent.sh, OpenMPI over TCP only, the
# frames through netns_relay (bench/mpi/netns_run.sh does all of it). Checks: each rank on its own
# host (name and address 10.199.0.1-3), the sums and the ring's bytes right, and the ring's bytes
# really crossed the relay (each host's link carried at least the frames the ring's bytes need);
# then the same with the relay dropping 3 % of the frames, which TCP must survive; then the DEM
# as the MPI job in a co-simulation whose master runs on another host (below).
# Exit 77 (skipped) only where rig.sh check says the rig cannot be built here (not root, no
# network namespaces).
set -uo pipefail
src=$1 bin=$2
run="$src/bench/mpi/netns_run.sh"
why=$(bash "$src/tests/netns/rig.sh" check) || { echo "netns rig skipped: $why"; exit 77; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# probe_over_rig TAG LOSS MB ROUNDS
probe_over_rig() {
  local tag=$1 loss=$2 mb=$3 rounds=$4
  local log="$work/$tag.log" relay="$work/$tag.relay"
  timeout 120 bash "$run" --hosts 3 --loss "$loss" --prefix "mt$(($$ % 100000))" --bin "$bin" --relay-log "$relay" \
    -- mpi_probe --ranks 3 --distinct-hosts --mb "$mb" --rounds "$rounds" >"$log" 2>&1
  local rc=$?
  cat "$log"
  if [ "$rc" -ne 0 ]; then fail "$tag: netns_run/mpirun exited $rc"; return; fi
  grep -q "3 ranks on 3 hosts, ring $mb MB x $rounds rounds: all checks passed" "$log" ||
    fail "$tag: mpi_probe's summary missing"
  local i
  for i in 1 2 3; do
    grep -q "mpi_probe: rank $((i - 1)) on mt[0-9]*[abc] (10.199.0.$i)" "$log" ||
      fail "$tag: rank $((i - 1)) did not run on host 10.199.0.$i"
  done
  # Every rank sent mb x rounds MiB to its neighbour in frames of at most 1500 bytes (MTU):
  # each host's link into the relay must have carried at least that many frames.
  local need=$((mb * rounds * 1048576 / 1500)) h got
  for h in a b c; do
    got=$(sed -n "s/^netns_relay: mt[0-9]*${h}1: received \([0-9]*\),.*/\1/p" "$relay")
    if [ -z "$got" ]; then fail "$tag: no relay count for host $h"; continue; fi
    [ "$got" -ge "$need" ] || fail "$tag: host $h sent $got frames through the relay, the ring needs >= $need"
    echo "$tag: host $h: $got frames through the relay (ring needs >= $need)"
  done
  if [ "$loss" != 0 ]; then
    local dropped
    dropped=$(sed -n 's/.*, dropped \([0-9]*\),.*/\1/p' "$relay" | awk '{s += $1} END {print s + 0}')
    [ "$dropped" -gt 0 ] || fail "$tag: the relay dropped no frame at loss $loss"
    echo "$tag: the relay dropped $dropped frames"
  fi
}

probe_over_rig clean 0 4 2
probe_over_rig loss3 0.03 2 2

# The DEM as the MPI job on 2 ranks in hosts a and b (dem_service under mpirun: rank 0 on the
# bus, rank 1 following it over MPI/TCP through the relay) and the co-simulation master with the
# prescribed blade in host c (netns_run.sh --beside), a keyed bus with ttl=1 through the relay:
# it finishes (the blade in the bed, above 100 N) and records the blade's wrench equal to the same
# co-simulation with one DEM rank on this host to round-off (1e-9 of the peak over these 15 ms,
# before the bed's chaos amplifies it; docs/mpi.md).
url='udpm://239.255.76.67:7667?ttl=1'
"$bin/cosim_master" --new-key "$work/key" >/dev/null 2>&1 || fail "cosim_master --new-key"
(
  cd "$src" || exit 1
  COSIM_KEY_FILE="$work/key" timeout 200 bash "$run" --hosts 2 --np 2 --prefix "mt$(($$ % 100000))" --bin "$bin" \
    --beside "'$bin/cosim_master' tests/dem_service/cosim.yaml --set 'bus.url=$url' --set participants.dem.launch=null \
              --set time.end=0.015 --set time.macro_step=2e-5 --output '$work/rig.h5'" \
    -- dem_service tests/dem_service/scene.yaml --name dem --bus "$url" --wait 60
) >"$work/cosim.log" 2>&1 || { fail "cosim over the rig: netns_run exited non-zero"; tail -40 "$work/cosim.log"; }
(cd "$src" && timeout 120 "$bin/cosim_master" tests/dem_service/cosim.yaml --set time.end=0.015 \
  --set time.macro_step=2e-5 --output "$work/one_host.h5") >"$work/one_host.log" 2>&1 || { fail "cosim on one host failed"; tail -20 "$work/one_host.log"; }
verdict=$(/usr/bin/python3 - "$work/rig.h5" "$work/one_host.h5" <<'PY' 2>&1
import sys, h5py, numpy as np
a, b = (h5py.File(f, "r") for f in sys.argv[1:3])
status = a["status"][()]
status = status.decode() if isinstance(status, bytes) else str(status)
wa, wb = (f["participants/dem/outputs/blade"][:] for f in (a, b))
peak = np.abs(wb[:, :3]).max()
diff = np.abs(wa - wb).max() if wa.shape == wb.shape else float("inf")
same = diff <= 1e-9 * peak
print(f"status {status}, {len(wa)} wrenches, max |F| {np.abs(wa[:, :3]).max():.3g} N, "
      f"{'round-off' if same else 'DIFFERENT'} to one rank on one host "
      f"(max |difference| {diff:.3g} N, {diff / peak:.3g} of the peak)")
PY
)
echo "cosim over the rig: $verdict"
# 750 macro steps; the blade meets the bed at 8.7 ms (peak above 1 kN)
[[ $verdict == "status finished, 751 wrenches, max |F| "*" N, round-off to one rank on one host"* ]] &&
  /usr/bin/python3 -c "import sys; sys.exit(not float(sys.argv[1]) > 100)" "$(sed 's/.*max |F| \([^ ]*\) N.*/\1/' <<<"$verdict")" ||
  { fail "cosim over the rig: $verdict"; tail -40 "$work/cosim.log"; }
grep -q "netns_run: mpirun exited 0, the command in host c 0" "$work/cosim.log" || fail "cosim over the rig: exit lines"
grep -q "dem_service: 2 ranks; rank 0 is the participant on the bus" "$work/cosim.log" || fail "cosim over the rig: not 2 DEM ranks"
grep -q "netns_run: 2 ranks on 2 hosts" "$work/cosim.log" || fail "cosim over the rig: the DEM's ranks not on 2 hosts"

[ "$fails" -eq 0 ] || { echo "mpi_netns_test: $fails check(s) failed"; exit 1; }
echo "mpi_netns_test: all checks passed"
