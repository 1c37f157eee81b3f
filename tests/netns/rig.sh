#!/usr/bin/env bash
# The multi-host test rig: three network namespaces (hosts) joined through a fourth (the
# switch), where netns_relay forwards frames between the hosts' links and impairs them.
#
#   rig.sh up PREFIX      creates PREFIXsw and the hosts PREFIXa, PREFIXb, PREFIXc (root)
#   rig.sh down PREFIX    removes them (and whatever runs in them)
#   rig.sh check          exit 0 if this machine can build the rig, else 77 with the reason
#
# Host h (a, b, c = 10.199.0.1, .2, .3) has eth0, one end of a veth pair whose other end,
# PREFIXh1, lies in the switch namespace; nothing connects the links there but the relay:
#   ip netns exec PREFIXsw netns_relay --seed 1 PREFIXa1:loss=0.05 PREFIXb1:... PREFIXc1:...
# Each host routes multicast (224.0.0.0/4) to eth0; the bus URL needs ttl=1 to leave a host:
#   ip netns exec PREFIXb oscillator_adapter --bus 'udpm://239.255.76.67:7667?ttl=1' ...
# PREFIX: at most 10 characters (device names have 15).
set -euo pipefail

check() {
  if [ "$(id -u)" != 0 ]; then echo "the netns rig needs root (ip netns add)"; return 77; fi
  if ! command -v ip >/dev/null; then echo "no 'ip' command (iproute2)"; return 77; fi
  local probe="cosimprobe$$"
  if ! ip netns add "$probe" 2>/dev/null; then echo "'ip netns add' fails here (no network namespaces)"; return 77; fi
  ip netns del "$probe"
  return 0
}

up() {
  local p=$1 i=1
  ip netns add "${p}sw"
  ip -n "${p}sw" link set lo up
  for h in a b c; do
    ip netns add "$p$h"
    ip link add "$p${h}0" type veth peer name "$p${h}1"
    ip link set "$p${h}0" netns "$p$h"
    ip link set "$p${h}1" netns "${p}sw"
    ip -n "$p$h" link set "$p${h}0" name eth0
    ip netns exec "$p$h" sysctl -qw net.ipv6.conf.all.disable_ipv6=1 2>/dev/null || true
    ip netns exec "${p}sw" sysctl -qw "net.ipv6.conf.$p${h}1.disable_ipv6=1" 2>/dev/null || true
    ip -n "$p$h" addr add "10.199.0.$i/24" dev eth0
    ip -n "$p$h" link set lo up
    ip -n "$p$h" link set eth0 up
    ip -n "$p$h" route add 224.0.0.0/4 dev eth0
    # The relay completes partial UDP checksums itself, not TCP's: TCP (MPI across the hosts,
    # docs/mpi.md) crosses the relay only with the offload off, which needs ethtool
    # (scripts/setup.sh installs it; bench/mpi/netns_run.sh refuses to run without it).
    if command -v ethtool >/dev/null; then ip netns exec "$p$h" ethtool -K eth0 tx off >/dev/null 2>&1 || true; fi
    ip -n "${p}sw" link set "$p${h}1" up
    i=$((i + 1))
  done
}

down() {
  local p=$1
  for ns in "${p}a" "${p}b" "${p}c" "${p}sw"; do
    if ip netns pids "$ns" >/dev/null 2>&1; then
      for pid in $(ip netns pids "$ns"); do kill -9 "$pid" 2>/dev/null || true; done
    fi
    ip netns del "$ns" 2>/dev/null || true
  done
}

case "${1:-}" in
  check) check ;;
  up) [ -n "${2:-}" ] || { echo "usage: rig.sh up PREFIX" >&2; exit 2; }; up "$2" ;;
  down) [ -n "${2:-}" ] || { echo "usage: rig.sh down PREFIX" >&2; exit 2; }; down "$2" ;;
  *) echo "usage: rig.sh check | up PREFIX | down PREFIX" >&2; exit 2 ;;
esac
