#!/usr/bin/env bash
# The same MPI job on one host and across two hosts of the namespace rig (not a test; root;
# docs/mpi.md, "Across hosts"). Three ways, in turn, --repeats rounds:
#   shm    N ranks on this host, plain mpirun (shared memory between the ranks)
#   tcp    N ranks on this host, TCP only (--mca pml ob1 --mca btl tcp,self)
#   rig    N ranks on two rig hosts (bench/mpi/netns_run.sh: TCP through netns_relay)
# shm and tcp run with OpenMPI's defaults (idle ranks poll; they yield when oversubscribed); rig
# with netns_run.sh's mpi_yield_when_idle 1 (its hosts and the relay share this machine's
# cores: polling ranks starve the relay). Prints the median time of each (min-max) and its
# ratio to shm, the anchor measured in the same run; keeps every run's output in --dir. The
# time is the wall time of the whole command (for rig: with the rig's setup, about a second),
# or with --metric RE the number RE's first group captures in the program's output (e.g.
# dem_run's loop time).
#
#   bash bench/mpi/hosts_compare.sh [--np 2] [--repeats 3] [--dir results/bench_mpi]
#        [--bin build/bin] [--metric RE] -- PROGRAM [ARGS...]
#   bash bench/mpi/hosts_compare.sh --metric 'median ([0-9.]+) us' -- mpi_probe --mb 1 --pingpong 2000
#   bash bench/mpi/hosts_compare.sh --metric 'Loop time of ([0-9.]+) s' \
#        -- dem_run tests/dem_service/scene.yaml --set run.duration=0.01
#
# A PROGRAM that writes a file must write it somewhere each run may replace (it is run 3 x
# repeats times). The ranks fill hosts in order (ranks 0..N/2-1 on host a).
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
np=2 repeats=3 dir="$repo/results/bench_mpi" bin="$repo/build/bin" metric=""
bad() { echo "hosts_compare: $*" >&2; exit 2; }
while [ $# -gt 0 ]; do
  case "$1" in
    --np) [ $# -ge 2 ] || bad "--np needs a number"; np=$2; shift 2 ;;
    --repeats) [ $# -ge 2 ] || bad "--repeats needs a number"; repeats=$2; shift 2 ;;
    --dir) [ $# -ge 2 ] || bad "--dir needs a folder"; dir=$2; shift 2 ;;
    --bin) [ $# -ge 2 ] || bad "--bin needs a folder"; bin=$2; shift 2 ;;
    --metric) [ $# -ge 2 ] || bad "--metric needs a regular expression with one group"; metric=$2; shift 2 ;;
    -h|--help) sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
    --) shift; break ;;
    *) bad "unknown option '$1'; put the program after --" ;;
  esac
done
[ $# -ge 1 ] || bad "no program: bash bench/mpi/hosts_compare.sh [options] -- PROGRAM [ARGS...]"
[[ $np =~ ^[1-9][0-9]*$ ]] || bad "--np $np: expected a rank count"
[[ $repeats =~ ^[1-9][0-9]*$ ]] || bad "--repeats $repeats: expected a whole number"
program=$1; shift
if [[ $program != */* ]] && [ -x "$bin/$program" ]; then program="$bin/$program"; fi
command -v "$program" >/dev/null || bad "program '$program' not found (build it, or give --bin)"
program=$(command -v "$program")
mkdir -p "$dir"
stamp=$(date -u +%Y%m%d_%H%M%S)

local_mpirun=(mpirun --allow-run-as-root --oversubscribe -np "$np")
declare -A times
run_one() {  # MODE ROUND
  local mode=$1 round=$2 log="$dir/${stamp}_$1_$2.log" t0 t1 rc
  shift 2
  t0=$(date +%s.%N)
  set +e
  case "$mode" in
    shm) "${local_mpirun[@]}" "$program" "$@" >"$log" 2>&1 ;;
    tcp) "${local_mpirun[@]}" --mca pml ob1 --mca btl tcp,self "$program" "$@" >"$log" 2>&1 ;;
    rig) bash "$repo/bench/mpi/netns_run.sh" --hosts 2 --np "$np" --bin "$bin" -- "$program" "$@" >"$log" 2>&1 ;;
  esac
  rc=$?
  set -e
  t1=$(date +%s.%N)
  [ "$rc" -eq 0 ] || { echo "hosts_compare: $mode round $round failed (exit $rc), see $log" >&2; tail -5 "$log" >&2; exit 1; }
  local value
  if [ -n "$metric" ]; then
    value=$(/usr/bin/python3 -c 'import re, sys
m = re.search(sys.argv[1], open(sys.argv[2], errors="replace").read())
print(m.group(1) if m else "")' "$metric" "$log")
    [ -n "$value" ] || { echo "hosts_compare: --metric '$metric' matches nothing in $log" >&2; exit 1; }
  else
    value=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
  fi
  times[$mode]+="$value "
  echo "  $mode round $round: $value" >&2
}
shift_args=("$@")
for round in $(seq 1 "$repeats"); do
  for mode in shm tcp rig; do run_one "$mode" "$round" "${shift_args[@]}"; done
done

echo "hosts_compare: $np ranks of $(basename "$program") $*, $repeats rounds, ${metric:-wall time (s)} per run (load: $(cut -d' ' -f1-3 /proc/loadavg))"
median() { tr ' ' '\n' | grep . | sort -g | awk '{ v[NR] = $1 } END { m = (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2; printf "%.2f %.2f %.2f", m, v[1], v[NR] }'; }
read -r anchor _ _ <<<"$(median <<<"${times[shm]}")"
printf '%-5s %10s %16s %10s\n' way median min-max "x shm"
for mode in shm tcp rig; do
  read -r m lo hi <<<"$(median <<<"${times[$mode]}")"
  printf '%-5s %10s %16s %10s\n' "$mode" "$m" "$lo-$hi" "$(awk -v m="$m" -v a="$anchor" 'BEGIN { printf "%.2f", m / a }')"
done
echo "logs: $dir/${stamp}_*.log"
