#!/usr/bin/env bash
# Installs every Debian 12 package the project builds, tests and plots with.
# Idempotent; run as root (CI and the README's commands call it).
# MPI (docs/mpi.md): OpenMPI's mpirun refuses to start, even on one host, unless an rsh agent
# (ssh) exists, hence openssh-client (openmpi-bin depends on it as well); ethtool switches off
# the checksum offload of the netns rig's hosts (tests/netns/rig.sh), without which TCP does not
# cross its relay.
set -euo pipefail
packages=(
  build-essential cmake pkg-config git
  liblcm-dev liblcm-bin libglib2.0-dev
  libeigen3-dev libassimp-dev libhdf5-dev libyaml-cpp-dev
  libgtest-dev libgmock-dev libomp-dev
  libsimbody-dev
  libsodium-dev
  libminizip-dev libpugixml-dev
  python3-matplotlib python3-h5py python3-numpy python3-yaml
  python3-paraview xvfb xauth ffmpeg
  iproute2 util-linux ethtool openssh-client
  clang libclang-rt-14-dev
  openmpi-bin libopenmpi-dev
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
echo "setup: all packages present"
