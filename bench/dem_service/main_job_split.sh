#!/usr/bin/env bash
# Where the main job's CPU goes: `cosim_master configs/wheel_loader.yaml` over a short horizon
# (default 4 s: the bucket enters the pile at about 2 s), with the CPU seconds (user + sys) of
# the master, the loader (wheel_loader_adapter) and the soil (dem_service) read from /proc every
# 0.2 s while they run, beside the wall time, the master's section table and the DEM's. CPU
# seconds are the measure a shared host distorts least; the wall time only counts on a quiet one.
# docs/performance.md, "The main job".
#
#   bash bench/dem_service/main_job_split.sh [--end 4] [--name split] [--bin build/bin]
#                                            [--soil 'K: V'] [--set K=V ...]
#
# --soil adds to the soil's parameters (e.g. --soil 'scene.threads: 1'); --set goes to cosim_master.
# --bin runs another build's binaries (the master starts the participants beside itself).
# Needs a build (bash scripts/build.sh) and the pile (bash scripts/prepare_pile_dry_sand.sh).
# Output: results/main_job_split/NAME.{log,h5,cpu}.
set -euo pipefail
cd "$(dirname "$0")/../.."
end=4 name=split bin=build/bin sets=() soil=
while [ $# -gt 0 ]; do
  case "$1" in
    --end) end="${2:?--end needs simulated seconds}"; shift 2 ;;
    --name) name="${2:?--name needs a name}"; shift 2 ;;
    --bin) bin="${2:?--bin needs a folder}"; shift 2 ;;
    --set) sets+=(--set "${2:?--set needs KEY=VALUE}"); shift 2 ;;
    --soil) soil="$soil, ${2:?--soil needs 'key: value'}"; shift 2 ;;
    -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
    *) echo "main_job_split: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ "$end" =~ ^[0-9]*\.?[0-9]+$ ]] && awk "BEGIN{exit !($end > 0)}" ||
  { echo "main_job_split: --end must be a positive number of seconds, got '$end'" >&2; exit 2; }
[[ "$name" =~ ^[A-Za-z0-9_.-]+$ ]] || { echo "main_job_split: --name may hold letters, digits, _ . - only" >&2; exit 2; }
for b in cosim_master dem_service wheel_loader_adapter; do
  [ -x "$bin/$b" ] || { echo "main_job_split: $bin/$b is missing: run bash scripts/build.sh first" >&2; exit 2; }
done
[ -f results/pile_dry_sand.h5 ] ||
  { echo "main_job_split: results/pile_dry_sand.h5 is missing: run bash scripts/prepare_pile_dry_sand.sh first" >&2; exit 2; }
out=results/main_job_split
mkdir -p "$out"
port=$((8400 + RANDOM % 400))
echo "main_job_split: $end s of the main job ($name); load average $(cut -d' ' -f1-3 /proc/loadavg)"
start=$(date +%s.%N)
nice "$bin/cosim_master" configs/wheel_loader.yaml --output "$out/$name.h5" --set output.csv= \
  --set output.progress=off --set "time.end=$end" --set "bus.url=udpm://239.255.76.67:$port?ttl=0" \
  --set "participants.soil.parameters={output.file: $out/${name}_soil.h5$soil}" "${sets[@]}" > "$out/$name.log" 2>&1 &
master=$!
/usr/bin/python3 - "$master" "$out/$name.cpu" <<'EOF' &
# CPU seconds per process of the job (the master and its children), last value seen of each.
import os, sys, time
master, path = int(sys.argv[1]), sys.argv[2]
tick = os.sysconf("SC_CLK_TCK")
seen = {}
def stat(pid):
    with open(f"/proc/{pid}/stat") as f:
        s = f.read()
    rest = s[s.rindex(")") + 2:].split()
    # The program's name from argv[0] (dem_service re-executes itself: its comm is then "exe").
    with open(f"/proc/{pid}/cmdline", "rb") as f:
        name = os.path.basename(f.read().split(b"\0")[0].decode(errors="replace")) or "?"
    return name, int(rest[1]), (int(rest[11]) + int(rest[12])) / tick  # ppid, utime + stime
while os.path.exists(f"/proc/{master}"):
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            name, ppid, cpu = stat(int(pid))
        except (OSError, ValueError, IndexError):
            continue
        if int(pid) == master or ppid == master:
            if name == "?" and int(pid) in seen:  # exiting: its cmdline is gone
                name = seen[int(pid)][0]
            seen[int(pid)] = (name, cpu)
    time.sleep(0.2)
with open(path, "w") as f:
    for pid, (name, cpu) in sorted(seen.items()):
        if name not in ("nice", "time") and cpu > 0:
            f.write(f"{name} {cpu:.2f}\n")
EOF
sampler=$!
rc=0
wait $master || rc=$?
wait $sampler || true
wall=$(awk "BEGIN{printf \"%.1f\", $(date +%s.%N) - $start}")
[ $rc = 0 ] || { echo "main_job_split: the run failed (exit $rc); see $out/$name.log" >&2; exit 1; }
echo "main_job_split: load average at the end $(cut -d' ' -f1-3 /proc/loadavg)"
/usr/bin/python3 - "$out/$name.cpu" "$end" "$wall" <<'EOF'
import sys
path, end, wall = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
rows = [line.split() for line in open(path) if line.strip()]
total = sum(float(c) for _, c in rows)
print(f"{'process':<24} {'CPU s':>8} {'per sim s':>10} {'share':>7}")
for name, cpu in rows:
    c = float(cpu)
    print(f"{name:<24} {c:8.2f} {c / end:10.2f} {100 * c / total:6.1f}%")
print(f"{'all':<24} {total:8.2f} {total / end:10.2f}   wall {wall:.1f} s, RTF {wall / end:.2f}")
EOF
echo "--- the master's and the DEM's tables ($out/$name.log):"
sed -n '/^Section/,/^$/p' "$out/$name.log"
grep -E "^(Broad phases|Sleeping|Real-time)" "$out/$name.log" || true
