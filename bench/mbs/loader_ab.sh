#!/usr/bin/env bash
# Two builds of the wheel loader stepped alone on the same recorded soil wrench, interleaved
# (A, B, A, B, ...): the CPU seconds of the stepping per simulated second of each, their ratio
# B/A per repeat and the median, and whether every output of every step is the same bytes
# (docs/performance.md, "The loader alone"). CPU seconds, not wall: the host is shared.
#
#   bash bench/mbs/loader_ab.sh --a OLD/bin --b build/bin [--wrench FILE.f64] [--end 3.5]
#                               [--repeats 3] [--average 0|1] [--params '{...}']
#
# --a/--b: folders holding a loader_alone each (build/bin of two builds, or a copy of one).
# --wrench: bench/mbs/export_wrench.py's file from a master record of the main job (without it
# the wrench is zero: the approach, no soil). --params goes to both (e.g. '{inner_step: 2e-4}').
set -euo pipefail
cd "$(dirname "$0")/../.."
a= b=build/bin wrench= end=3.5 repeats=3 average=0 params='{}'
while [ $# -gt 0 ]; do
  case "$1" in
    --a) a="${2:?}"; shift 2 ;;
    --b) b="${2:?}"; shift 2 ;;
    --wrench) wrench="${2:?}"; shift 2 ;;
    --end) end="${2:?}"; shift 2 ;;
    --repeats) repeats="${2:?}"; shift 2 ;;
    --average) average="${2:?}"; shift 2 ;;
    --params) params="${2:?}"; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "loader_ab: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[ -n "$a" ] || { echo "loader_ab: --a OLD_BIN_FOLDER is required" >&2; exit 2; }
for d in "$a" "$b"; do
  [ -x "$d/loader_alone" ] || { echo "loader_ab: $d/loader_alone is missing (cmake --build build --target loader_alone)" >&2; exit 2; }
done
[[ "$repeats" =~ ^[1-9][0-9]*$ ]] || { echo "loader_ab: --repeats must be a positive whole number" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
args=(--end "$end" --average "$average" --params "$params")
[ -n "$wrench" ] && args+=(--wrench "$wrench")
echo "loader_ab: $end s, $repeats repeats, average $average, params $params; load average $(cut -d' ' -f1-3 /proc/loadavg)"
ratios=()
for r in $(seq "$repeats"); do
  ca=$(nice -n 19 "$a/loader_alone" "${args[@]}" --out "$tmp/a.f64" | sed -n 's/^stepping [0-9.]* CPU s: \([0-9.]*\) CPU s per simulated s.*/\1/p')
  cb=$(nice -n 19 "$b/loader_alone" "${args[@]}" --out "$tmp/b.f64" | sed -n 's/^stepping [0-9.]* CPU s: \([0-9.]*\) CPU s per simulated s.*/\1/p')
  same=$(cmp -s "$tmp/a.f64" "$tmp/b.f64" && echo "same bytes" || echo "OUTPUTS DIFFER")
  ratio=$(awk "BEGIN{printf \"%.3f\", $cb / $ca}")
  ratios+=("$ratio")
  echo "repeat $r: A $ca, B $cb CPU s per simulated s; B/A $ratio; $same"
done
median=$(printf '%s\n' "${ratios[@]}" | sort -n | awk '{v[NR]=$1} END{print (NR%2 ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2)}')
echo "median B/A $median; load average after $(cut -d' ' -f1-3 /proc/loadavg)"
