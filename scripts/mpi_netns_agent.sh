#!/usr/bin/env bash
# OpenMPI's remote-start agent for the network-namespace rig (tests/netns/rig.sh): it stands in
# for ssh. mpirun calls it as
#     mpi_netns_agent.sh [ssh-like options] HOST COMMAND...
# and it runs COMMAND (a shell command line, as ssh would) inside the namespace that plays HOST,
# with its own UTS namespace whose host name is the namespace's name, so every rank reports a
# different host. No ssh, no keys: the rig is on this machine and the agent needs root.
#
# HOST is either the name of an existing network namespace (e.g. mpia) or a rig address
# 10.199.0.1, .2, .3, which maps to PREFIXa, PREFIXb, PREFIXc with PREFIX from the environment
# variable MPI_NETNS_PREFIX (mpirun passes its environment on to the agent).
#
#     mpirun --mca plm_rsh_agent "$PWD/scripts/mpi_netns_agent.sh" --host 10.199.0.1,10.199.0.2 ...
#
# bench/mpi/netns_run.sh brings the rig up and runs mpirun with every setting this needs;
# docs/mpi.md ("Across hosts") gives the command in full.
set -euo pipefail

die() { echo "mpi_netns_agent: $*" >&2; exit 255; }

# ssh options OpenMPI or a user's plm_rsh_args may put before the host: skip them (and the
# argument of those that take one).
while [ $# -gt 0 ]; do
  case "$1" in
    -[bcDEeFIiJLlmOopQRSWw]) [ $# -ge 2 ] || die "option $1 without its argument"; shift 2 ;;
    -[bcDEeFIiJLlmOopQRSWw]?*) shift ;;
    --) shift; break ;;
    -*) shift ;;
    *) break ;;
  esac
done
[ $# -ge 2 ] || die "usage: mpi_netns_agent.sh [options] HOST COMMAND... (got: $*)"
host=$1; shift
host=${host#*@}   # user@host: the user is meaningless here

if [[ $host =~ ^10\.199\.0\.([123])$ ]]; then
  [ -n "${MPI_NETNS_PREFIX:-}" ] ||
    die "host $host is a rig address but MPI_NETNS_PREFIX is not set (export the rig's prefix, e.g. MPI_NETNS_PREFIX=mpi for mpia/mpib/mpic)"
  letters=(x a b c)
  ns=${MPI_NETNS_PREFIX}${letters[${BASH_REMATCH[1]}]}
else
  ns=$host
fi
ip netns list 2>/dev/null | awk '{print $1}' | grep -qx -- "$ns" ||
  die "no network namespace '$ns' for host '$host' (is the rig up? bash tests/netns/rig.sh up PREFIX; hosts are 10.199.0.1-3 or namespace names)"

# COMMAND is a command line for the remote shell; OpenMPI assumes the remote shell is the local
# one ($SHELL), so run it with that (plm_rsh_assume_same_shell).
shell=${SHELL:-/bin/sh}
exec ip netns exec "$ns" unshare --uts -- /bin/sh -c 'hostname "$1" && shift && exec "$@"' agent "$ns" "$shell" -c "$*"
