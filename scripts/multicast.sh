#!/usr/bin/env bash
# LCM multicast needs a route for 224.0.0.0/4. A host with a default route has one; on a
# host with only loopback, send multicast over lo (needs root).
set -u
# The bus recorder (--record) asks for a 4 MiB receive buffer; the kernel grants at most this.
[ "$(cat /proc/sys/net/core/rmem_max 2>/dev/null || echo 0)" -ge 4194304 ] || sysctl -qw net.core.rmem_max=4194304 2>/dev/null || true
if ip route get 239.255.76.67 >/dev/null 2>&1; then exit 0; fi
ip link set lo up 2>/dev/null
ip route add 224.0.0.0/4 dev lo 2>/dev/null || {
  echo "multicast: no route for 224.0.0.0/4; as root run: ip route add 224.0.0.0/4 dev lo" >&2
  exit 1
}
