#!/usr/bin/env bash
# The main job's cost against its anchor, measured in the same run: `cosim_master
# configs/wheel_loader.yaml` as it is (today's setting) and with the DEM setting of before its
# speed ensembles (dt 1e-4 s, every grain awake: the anchor), each on its own LCM URL, under
# /usr/bin/time. Prints per run the CPU seconds of the master and its participants (user + sys),
# the CPU seconds per simulated second, the wall time and the real-time factor, then the ratio of
# CPU seconds today / anchor (the figure a shared host distorts least) and, with --anchor-rtf, the
# real-time factor that ratio projects from a quiet-host measurement of the anchor.
# docs/performance.md, "The main job".
#
#   bash bench/dem_service/main_job_cpu.sh [--end 15] [--repeats 1] [--together] [--anchor-rtf 9.07]
#
# --together runs the two at once (2 cores: each gets about one), otherwise in turn (anchor
# first). Needs a build (bash scripts/build.sh) and the pile (bash scripts/prepare_pile_dry_sand.sh).
# Output: results/main_job_cpu/ (the masters' records and logs).
set -euo pipefail
cd "$(dirname "$0")/../.."
end=15 repeats=1 together=0 anchor_rtf=""
while [ $# -gt 0 ]; do
  case "$1" in
    --end) end="${2:?--end needs simulated seconds}"; shift 2 ;;
    --repeats) repeats="${2:?--repeats needs a count}"; shift 2 ;;
    --together) together=1; shift ;;
    --anchor-rtf) anchor_rtf="${2:?--anchor-rtf needs a real-time factor}"; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "main_job_cpu: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ "$end" =~ ^[0-9]*\.?[0-9]+$ ]] && awk "BEGIN{exit !($end > 0)}" ||
  { echo "main_job_cpu: --end must be a positive number of seconds, got '$end'" >&2; exit 2; }
[[ "$repeats" =~ ^[1-9][0-9]*$ ]] || { echo "main_job_cpu: --repeats must be a whole number >= 1, got '$repeats'" >&2; exit 2; }
if [ -n "$anchor_rtf" ]; then
  [[ "$anchor_rtf" =~ ^[0-9]*\.?[0-9]+$ ]] ||
    { echo "main_job_cpu: --anchor-rtf must be a positive number, got '$anchor_rtf'" >&2; exit 2; }
fi
for b in cosim_master dem_service wheel_loader_adapter; do
  [ -x "build/bin/$b" ] || { echo "main_job_cpu: build/bin/$b is missing: run bash scripts/build.sh first" >&2; exit 2; }
done
[ -f results/pile_dry_sand.h5 ] ||
  { echo "main_job_cpu: results/pile_dry_sand.h5 is missing: run bash scripts/prepare_pile_dry_sand.sh first" >&2; exit 2; }
[ -x /usr/bin/time ] || { echo "main_job_cpu: /usr/bin/time is missing (Debian package 'time')" >&2; exit 2; }

out=results/main_job_cpu
mkdir -p "$out"
declare -A extra=(
  [anchor]="participants.soil.parameters={scene.dt: 1.0e-4, scene.sleep.enabled: false, output.file: $out/anchor_soil.h5}"
  [today]="participants.soil.parameters={output.file: $out/today_soil.h5}"
)
declare -A port=([anchor]=8196 [today]=8197)

run() {  # NAME REPEAT
  local name=$1 r=$2
  nice /usr/bin/time -f "%e %U %S" -o "$out/$name.$r.time" build/bin/cosim_master configs/wheel_loader.yaml \
    --output "$out/$name.$r.h5" --set output.csv= --set output.progress=off --set "time.end=$end" \
    --set "bus.url=udpm://239.255.76.67:${port[$name]}?ttl=0" --set "${extra[$name]}" > "$out/$name.$r.log" 2>&1 ||
    { echo "main_job_cpu: the $name run failed; see $out/$name.$r.log" >&2; return 1; }
}

echo "main_job_cpu: $end s of the main job, $repeats repeat(s), $([ $together = 1 ] && echo together || echo in turn); load average $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq 1 "$repeats"); do
  if [ $together = 1 ]; then
    run anchor "$r" & a=$!
    run today "$r" & t=$!
    wait $a && wait $t
  else
    run anchor "$r"
    run today "$r"
  fi
done
echo "main_job_cpu: load average at the end $(cut -d' ' -f1-3 /proc/loadavg)"

/usr/bin/python3 - "$out" "$end" "$repeats" "$anchor_rtf" <<'EOF'
import statistics, sys
out, end, repeats, anchor_rtf = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
def read(name, r):
    wall, user, sys_ = (float(x) for x in open(f"{out}/{name}.{r}.time").read().split()[-3:])
    return wall, user + sys_
rows = {n: [read(n, r) for r in range(1, repeats + 1)] for n in ("anchor", "today")}
print(f"{'run':<44} {'CPU s':>8} {'CPU s/s':>8} {'wall s':>8} {'RTF':>6}")
labels = {"anchor": "anchor: dt 1e-4 s, all awake", "today": "today: configs/wheel_loader.yaml"}
for n in ("anchor", "today"):
    for r, (wall, cpu) in enumerate(rows[n], 1):
        print(f"{labels[n] + f' #{r}':<44} {cpu:8.1f} {cpu / end:8.2f} {wall:8.1f} {wall / end:6.2f}")
ratios = [t[1] / a[1] for a, t in zip(rows["anchor"], rows["today"])]
med = statistics.median(ratios)
print("CPU today / anchor: " + ", ".join(f"{x:.3f}" for x in ratios) + f" (median {med:.3f})")
if anchor_rtf:
    print(f"projected real-time factor (a projection, not a measurement): {float(anchor_rtf):g} x {med:.3f} = {float(anchor_rtf) * med:.2f}")
EOF
