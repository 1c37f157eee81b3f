#!/usr/bin/env bash
# mpi_netns_dem_test: dem_run decomposed over the rig's namespaced hosts (TCP through
# netns_relay, bench/mpi/netns_run.sh) records bit for bit what the same ranks record on one
# host (shared memory): 2 ranks on 2 hosts, and 3 ranks on 3 hosts with 3 % of the frames lost.
# Each rank reports its ghosts (the engine's MPI summary), and the relay carried at least the
# frames the ghosts' bytes need. Registered only when dem_run is built with MPI (target
# dem_mpi). Exit 77 (skipped) only where rig.sh check says the rig cannot be built here.
set -uo pipefail
src=$1 bin=$2
why=$(bash "$src/tests/netns/rig.sh" check) || { echo "netns rig skipped: $why"; exit 77; }
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
cd "$src" || exit 1
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
scene=(tests/dem_service/scene.yaml --set run.duration=0.002)   # 1500 grains, 200 steps

# rig_vs_one_host NP LOSS
rig_vs_one_host() {
  local np=$1 loss=$2 tag="np$1"
  timeout 200 bash bench/mpi/netns_run.sh --hosts "$np" --loss "$loss" --prefix "md$(($$ % 100000))" --bin "$bin" \
    --relay-log "$work/$tag.relay" -- dem_run "${scene[@]}" --output "$work/$tag.rig.h5" >"$work/$tag.rig.log" 2>&1 ||
    { fail "$tag: dem_run across the rig failed"; tail -30 "$work/$tag.rig.log"; return; }
  timeout 200 mpirun --allow-run-as-root --oversubscribe -np "$np" "$bin/dem_run" "${scene[@]}" \
    --output "$work/$tag.one.h5" >"$work/$tag.one.log" 2>&1 ||
    { fail "$tag: dem_run on one host failed"; tail -30 "$work/$tag.one.log"; return; }
  grep -q "^MPI: $np ranks" "$work/$tag.rig.log" || { fail "$tag: no 'MPI: $np ranks' summary"; tail -30 "$work/$tag.rig.log"; }
  local r ghosts bytes total_bytes=0
  for r in $(seq 0 $((np - 1))); do
    ghosts=$(sed -n "s/^  rank $r: [0-9]* owned, \([0-9]*\) ghosts.*/\1/p" "$work/$tag.rig.log")
    bytes=$(sed -n "s/^  rank $r: .*per step [0-9]* messages, \([0-9]*\) bytes sent.*/\1/p" "$work/$tag.rig.log")
    [ -n "$ghosts" ] && [ "$ghosts" -gt 0 ] || fail "$tag: rank $r reports no ghosts"
    [ -n "$bytes" ] && total_bytes=$((total_bytes + bytes))
  done
  # 200 steps of every rank's forward bytes in frames of at most 1500 bytes, over all links
  local need=$((200 * total_bytes / 1500)) got
  got=$(sed -n 's/.*: received \([0-9]*\),.*/\1/p' "$work/$tag.relay" | awk '{s += $1} END {print s + 0}')
  [ "$got" -ge "$need" ] || fail "$tag: $got frames through the relay, the ghosts' bytes need >= $need"
  echo "$tag: $got frames through the relay (the ghosts' bytes need >= $need)"
  if [ "$loss" != 0 ]; then
    local dropped
    dropped=$(sed -n 's/.*, dropped \([0-9]*\),.*/\1/p' "$work/$tag.relay" | awk '{s += $1} END {print s + 0}')
    [ "$dropped" -gt 0 ] || fail "$tag: the relay dropped no frame at loss $loss"
    echo "$tag: the relay dropped $dropped frames"
  fi
  local verdict
  verdict=$(/usr/bin/python3 - "$work/$tag.rig.h5" "$work/$tag.one.h5" <<'PY' 2>&1
import sys, h5py, numpy as np
def datasets(path):
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, np.asarray(o[()])) if isinstance(o, h5py.Dataset) else None)
    return out
a, b = datasets(sys.argv[1]), datasets(sys.argv[2])
differ = sorted(k for k in set(a) | set(b) if k not in a or k not in b or a[k].tobytes() != b[k].tobytes())
print(f"{len(a)} datasets, " + ("all bit-identical" if a and not differ else "differ: " + ", ".join(differ[:8])))
PY
)
  echo "$tag: rig against one host: $verdict"
  [[ $verdict == *"all bit-identical" ]] || fail "$tag: rig against one host: $verdict"
}

rig_vs_one_host 2 0
rig_vs_one_host 3 0.03

[ "$fails" -eq 0 ] || { echo "mpi_netns_dem_test: $fails check(s) failed"; exit 1; }
echo "mpi_netns_dem_test: all checks passed"
