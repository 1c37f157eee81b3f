#!/usr/bin/env bash
# Installs the Debian packages a benchmark's anchor needs, if missing, and checks that each
# package's command is there afterwards. Idempotent; needs root (like scripts/setup.sh).
#   bash bench/common/ensure_debian.sh NAME PACKAGE:COMMAND [PACKAGE:COMMAND ...]
# NAME prefixes the messages (the benchmark asking).
set -euo pipefail
name="$1"
shift
missing=()
for pc in "$@"; do
  p="${pc%%:*}"
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "$name: installing ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
for pc in "$@"; do
  p="${pc%%:*}" c="${pc#*:}"
  command -v "$c" >/dev/null || { echo "$name: $c not found after installing $p" >&2; exit 1; }
done
