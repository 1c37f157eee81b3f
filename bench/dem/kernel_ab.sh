#!/usr/bin/env bash
# The pair forces of two revisions, A/B in one process (not a test; docs/performance.md, "Full
# chunks, and the contact window in the bound"):
#
#   bash bench/dem/kernel_ab.sh REV_A REV_B [--checkpoint FILE.h5] [--config SCENE.yaml]
#                               [--passes 40] [--threads 1] [--close METRES]
#
# REV is a git revision, or "worktree" for the working copy of dem_service/src/pair_kernel.cpp.
# Both versions are compiled into one binary and timed alternately on the pair lists of a
# checkpoint (default: the paper scene's penetration checkpoint that bench/paper/paper_scene.sh
# writes, with the contact law and dt of bench/paper/paper_scene.yaml), so a machine whose speed
# drifts between minutes still compares them. It prints both medians, their ratio, how often B
# was faster, and whether the first pass gave the same forces. --close M: B reads only the close
# pairs within M metres of contact (performance.close_margin), A every candidate.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build}"
if [ $# -lt 2 ]; then
  sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
fi
rev_a=$1 rev_b=$2
shift 2
checkpoint=results/paper_bench/needed_1_penetration.h5
config=bench/paper/paper_scene.yaml
passes=40 threads=1 close=
while [ $# -gt 0 ]; do
  case "$1" in
    --checkpoint) checkpoint=$2; shift 2 ;;
    --config) config=$2; shift 2 ;;
    --passes) passes=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --close) close=$2; shift 2 ;;
    *) echo "kernel_ab: unknown option $1 (see the usage at the top of $0)" >&2; exit 2 ;;
  esac
done
if [ ! -f "$checkpoint" ]; then
  echo "kernel_ab: no checkpoint $checkpoint; run bash bench/paper/paper_scene.sh --policies needed" >&2
  echo "  first (it writes it), or pass --checkpoint a file with pair lists" >&2
  exit 2
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
src=dem_service/src/pair_kernel.cpp hdr=dem_service/include/dem/pair_kernel.hpp
get() {  # get REV PATH OUT
  if [ "$1" = worktree ]; then cp "$2" "$3"; else git show "$1:$2" > "$3"; fi
}
# The kernel's private parts beside it (pair_kernel_parts.hpp, pair_kernel_chunks.inc) are put
# in its text, so that each version is one source; the emulated kernel (a test's, another file)
# is left out: a stub stands for it.
inline_local() {  # inline_local REV FILE
  local rev=$1 file=$2 inc name
  while inc=$(grep -m1 -o '^#include "[a-z_0-9]*\.\(hpp\|inc\)"' "$file"); do
    name=${inc#\#include \"}
    name=${name%\"}
    get "$rev" "dem_service/src/$name" "$tmp/part" || { echo "kernel_ab: no $name at $rev" >&2; exit 2; }
    sed -i '/^#pragma once/d' "$tmp/part"
    sed -i -e "\|^#include \"$name\"|{r $tmp/part" -e 'd}' "$file"
  done
  if grep -q pair_rows_emulated "$file"; then
    cat >> "$file" <<'STUB'
namespace dem::detail {
void pair_rows_emulated(const PairRows&, const PairSleep*, std::size_t, std::size_t, std::size_t,
                        std::vector<PairRemote>&, PairRowStats&) {
  std::abort();
}
}  // namespace dem::detail
STUB
  fi
}
for v in a b; do
  rev=$rev_a; [ $v = b ] && rev=$rev_b
  get "$rev" "$src" "$tmp/kernel_$v.cpp" || { echo "kernel_ab: no $src at $rev" >&2; exit 2; }
  get "$rev" "$hdr" "$tmp/header_$v.hpp" || { echo "kernel_ab: no $hdr at $rev" >&2; exit 2; }
  inline_local "$rev" "$tmp/kernel_$v.cpp"
done
# The harness compiles both against the current header: their interfaces must agree (compared
# without comments and blank lines).
get worktree "$hdr" "$tmp/header_now.hpp"
for h in a b now; do
  sed -e 's://.*$::' -e '/^[[:space:]]*$/d' "$tmp/header_$h.hpp" > "$tmp/interface_$h"
done
if ! cmp -s "$tmp/interface_a" "$tmp/interface_now" || ! cmp -s "$tmp/interface_b" "$tmp/interface_now"; then
  echo "kernel_ab: $hdr differs between $rev_a, $rev_b and the working copy; compare revisions" >&2
  echo "  with the same interface" >&2
  exit 2
fi
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
fi
cmake --build "$build" -j2 --target dem_bench wheel_loader_meshes >/dev/null
# The flags of the engine (-ffp-contract=off as the engine), linked like dem_bench.
link=$(sed -e 's/^.* -o \.\.\/\.\.\/bin\/dem_bench //' "$build/bench/dem/CMakeFiles/dem_bench.dir/link.txt")
(cd "$build/bench/dem" && c++ -O3 -DNDEBUG -ffp-contract=off -fno-math-errno -fopenmp -std=c++20 -w \
  -I"$root/dem_service/include" -I"$root/protocol/support/include" -isystem /usr/include/hdf5/serial \
  -DKERNEL_A="\"$tmp/kernel_a.cpp\"" -DKERNEL_B="\"$tmp/kernel_b.cpp\"" \
  "$root/bench/dem/kernel_ab.cpp" -o "$tmp/kernel_ab" $link)
echo "A = $rev_a, B = $rev_b"
"$tmp/kernel_ab" "$config" "$checkpoint" "$passes" "$threads" ${close:+"$close"}
