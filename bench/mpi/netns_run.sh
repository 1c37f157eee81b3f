#!/usr/bin/env bash
# Runs a command as an MPI job across 2 or 3 hosts of the network-namespace rig
# (tests/netns/rig.sh): brings the rig up, starts netns_relay (the switch, optionally lossy),
# runs mpirun in host a with the rig's agent (scripts/mpi_netns_agent.sh) and OpenMPI over TCP
# only, then takes the rig down, also on failure or Ctrl-C. Root only (network namespaces).
#
#   bash bench/mpi/netns_run.sh [options] -- PROGRAM [ARGS...]
#
#   --hosts N        hosts to use: 2 (10.199.0.1-2) or 3 (default 2)
#   --np N           ranks (default: one per host); host a gets the first ceil(N/hosts), then b, ...
#   --loss P         the relay drops this fraction of the frames on every link (default 0)
#   --delay S        the relay delays every frame by S seconds (default 0)
#   --prefix P       namespace prefix, at most 8 characters (default mr<pid>)
#   --bin DIR        where netns_relay is and where a bare PROGRAM name is looked up first
#                    (default build/bin of this checkout)
#   --relay-log F    keep the relay's per-link counts (frames received, forwarded, dropped) in F
#   --mpirun-arg A   one more argument for mpirun (repeatable), e.g. --mpirun-arg -x
#                    --mpirun-arg OMP_NUM_THREADS=1
#   --beside CMD     with --hosts 2: run the shell command CMD in host c (10.199.0.3) while the
#                    MPI job runs, e.g. the co-simulation master whose DEM participant is the job
#                    (bus URL with ttl=1 on both sides); its exit status counts as well
# mpirun passes COSIM_KEY_FILE (the bus key, docs/security.md) to the ranks when it is set.
#
# Examples (docs/mpi.md, "Across hosts"):
#   bash bench/mpi/netns_run.sh --hosts 2 -- dem_run configs/dem/bed.yaml
#   bash bench/mpi/netns_run.sh --hosts 2 --beside "build/bin/cosim_master MASTER.yaml
#     --set bus.url=udpm://239.255.76.67:7667?ttl=1 --set participants.soil.launch=null" \
#     -- dem_service SOIL.yaml --name soil --bus 'udpm://239.255.76.67:7667?ttl=1' --wait 60
# Exit status: mpirun's (then CMD's); 77 if this machine cannot build the rig (not root, no
# namespaces); 2 for bad options.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)

hosts=2 np=0 loss=0 delay=0 prefix="mr$(($$ % 1000000))" bin="$repo/build/bin" relay_log=""
mpirun_extra=() beside=""
usage() { sed -n '2,30p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
bad() { echo "netns_run: $*" >&2; exit 2; }
number() { [[ $2 =~ ^[0-9]*\.?[0-9]+([eE][-+]?[0-9]+)?$ ]] || bad "$1 $2: expected a number"; }
while [ $# -gt 0 ]; do
  case "$1" in
    --hosts) [ $# -ge 2 ] || bad "--hosts needs 2 or 3"; hosts=$2; shift 2 ;;
    --np) [ $# -ge 2 ] || bad "--np needs a number of ranks"; np=$2; shift 2 ;;
    --loss) [ $# -ge 2 ] || bad "--loss needs a fraction"; number --loss "$2"; loss=$2; shift 2 ;;
    --delay) [ $# -ge 2 ] || bad "--delay needs seconds"; number --delay "$2"; delay=$2; shift 2 ;;
    --prefix) [ $# -ge 2 ] || bad "--prefix needs a name"; prefix=$2; shift 2 ;;
    --bin) [ $# -ge 2 ] || bad "--bin needs a folder"; bin=$2; shift 2 ;;
    --relay-log) [ $# -ge 2 ] || bad "--relay-log needs a file"; relay_log=$2; shift 2 ;;
    --mpirun-arg) [ $# -ge 2 ] || bad "--mpirun-arg needs an argument"; mpirun_extra+=("$2"); shift 2 ;;
    --beside) [ $# -ge 2 ] || bad "--beside needs a command"; beside=$2; shift 2 ;;
    -h|--help) usage ;;
    --) shift; break ;;
    *) bad "unknown option '$1' (see --help); put the program after --" ;;
  esac
done
[ $# -ge 1 ] || bad "no program to run: bash bench/mpi/netns_run.sh [options] -- PROGRAM [ARGS...]"
[[ $hosts =~ ^[23]$ ]] || bad "--hosts $hosts: the rig has 2 or 3 hosts to offer (a third is often the machine's)"
[[ $np =~ ^[0-9]+$ ]] || bad "--np $np: expected a whole number of ranks"
[ "$np" -gt 0 ] || np=$hosts
[[ $prefix =~ ^[A-Za-z0-9]{1,8}$ ]] || bad "--prefix $prefix: 1-8 letters or digits (device names have 15 characters)"
awk -v p="$loss" 'BEGIN { exit !(p >= 0 && p < 1) }' || bad "--loss $loss: expected a fraction in [0, 1)"
[ -z "$beside" ] || [ "$hosts" = 2 ] || bad "--beside runs in host c: use it with --hosts 2"

# The program: a bare name is looked up in --bin first, then on PATH; every host must find it
# at the same absolute path (the rig shares this machine's file system).
program=$1; shift
if [[ $program != */* ]]; then
  if [ -x "$bin/$program" ]; then program="$bin/$program"
  else program=$(command -v "$program") || bad "program '$1' not found in $bin or on PATH (build it first)"
  fi
fi
[ -x "$program" ] || bad "program '$program' is not an executable file"
program=$(cd "$(dirname "$program")" && pwd)/$(basename "$program")
relay="$bin/netns_relay"
[ -x "$relay" ] || bad "no $relay (cmake --build build --target netns_relay)"
command -v mpirun >/dev/null || bad "no mpirun: install openmpi-bin (bash scripts/setup.sh)"

why=$(bash "$repo/tests/netns/rig.sh" check) || { echo "netns_run: skipped: $why" >&2; exit 77; }
# The hosts' veths leave TCP checksums to the (absent) hardware; the relay forwards frames as
# read, so TCP through it needs checksum offload off on every host (rig.sh does it with ethtool).
command -v ethtool >/dev/null ||
  { echo "netns_run: TCP through the rig's relay needs ethtool (apt-get install ethtool; scripts/setup.sh installs it)" >&2; exit 1; }

work=$(mktemp -d)
relay_pid="" beside_pid=""
cleanup() {
  local rc=$?
  trap - EXIT INT TERM
  if [ -n "$beside_pid" ]; then kill -TERM "$beside_pid" 2>/dev/null || true; wait "$beside_pid" 2>/dev/null || true; fi
  if [ -n "$relay_pid" ]; then kill -TERM "$relay_pid" 2>/dev/null || true; wait "$relay_pid" 2>/dev/null || true; fi
  if [ -s "$work/relay.log" ]; then
    sed 's/^/  /' "$work/relay.log" >&2
    if [ -n "$relay_log" ]; then cp "$work/relay.log" "$relay_log"; fi
  fi
  bash "$repo/tests/netns/rig.sh" down "$prefix" || true
  rm -rf "$work"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

bash "$repo/tests/netns/rig.sh" down "$prefix" >/dev/null 2>&1 || true
bash "$repo/tests/netns/rig.sh" up "$prefix"
spec="loss=$loss,delay=$delay"
ip netns exec "${prefix}sw" "$relay" --seed 1 "${prefix}a1:$spec" "${prefix}b1:$spec" "${prefix}c1:$spec" \
  2>"$work/relay.log" &
relay_pid=$!
sleep 0.3

host_list="10.199.0.1"
for i in $(seq 2 "$hosts"); do host_list+=",10.199.0.$i"; done
slots=$(((np + hosts - 1) / hosts))
host_slots=$(echo "$host_list" | sed "s/\([0-9.]*\)/\1:$slots/g")

export MPI_NETNS_PREFIX=$prefix
mpirun_args=(
  --allow-run-as-root                                  # CI runs as root
  --oversubscribe                                      # more ranks than cores
  --mca plm_rsh_agent "$repo/scripts/mpi_netns_agent.sh"
  --mca plm_rsh_no_tree_spawn 1                        # every daemon started from host a
  --mca pml ob1 --mca btl tcp,self                     # TCP between ranks, no shared memory
  --mca btl_tcp_if_include 10.199.0.0/24
  --mca oob_tcp_if_include 10.199.0.0/24
  --mca mpi_yield_when_idle 1                          # the hosts share this machine's cores
  --host "$host_slots" --map-by slot -np "$np"           # fill host a first, then b, ...
  "${mpirun_extra[@]}"
)
if [ -n "${COSIM_KEY_FILE:-}" ]; then mpirun_args+=(-x COSIM_KEY_FILE); fi
in_host() {  # HOST COMMAND...: run in the rig's host with its own host name
  local h=$1; shift
  ip netns exec "$prefix$h" unshare --uts -- /bin/sh -c 'hostname "$1" && shift && exec "$@"' run "$prefix$h" "$@"
}
if [ -n "$beside" ]; then
  echo "netns_run: in host c (10.199.0.3): $beside" >&2
  in_host c bash -c "$beside" &
  beside_pid=$!
fi
echo "netns_run: $np ranks on $hosts hosts ($host_list), relay $spec" >&2
echo "netns_run: ip netns exec ${prefix}a mpirun ${mpirun_args[*]} $program $*" >&2
set +e
in_host a mpirun "${mpirun_args[@]}" "$program" "$@"
rc=$?
if [ -n "$beside_pid" ]; then
  wait "$beside_pid"
  beside_rc=$?
  beside_pid=""
  echo "netns_run: mpirun exited $rc, the command in host c $beside_rc" >&2
  [ "$rc" -ne 0 ] || rc=$beside_rc
fi
set -e
exit "$rc"
