#!/usr/bin/python3
"""Two dem_run binaries against each other on the same scene, interleaved (A B, B A, A B, ...),
so that a VM whose speed drifts between minutes hits both alike. Prints, per binary, the median
(and range) of each section of dem_run's timing table, the loop time and the process's CPU time
(user + system, from os.wait4), the context switches of all its threads (voluntary: a thread went to
sleep, e.g. an idle OpenMP thread at a barrier; involuntary: taken off its core), the 1-minute
load average before each run, and the ratio B / A of the medians. A ratio says something only
where the ranges do not overlap. Build the old binary from a worktree, e.g.

  git worktree add /tmp/old <commit> && cmake -S /tmp/old -B /tmp/old/build \\
      -DCMAKE_BUILD_TYPE=Release && cmake --build /tmp/old/build --target dem_run

usage: binary_ab.py A_DEM_RUN B_DEM_RUN CONFIG.yaml [--rounds 3] [--set KEY=VALUE ...]

On 2 threads a stalled vCPU stalls its barrier partner; --set scene.threads=1 is the steadier
ruler for work per step (docs/performance.md, "What a sleeper costs between the pair forces").
"""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROW = re.compile(r"^([a-z_]+)\s+\|\s+([0-9.]+)\s+\|")
LOOP = re.compile(r"Loop time of ([0-9.]+) s")


def run(binary, config, sets, out):
    cmd = [binary, config]
    for s in sets:
        cmd += ["--set", s]
    cmd += ["--output", out]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    text = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        sys.exit(f"binary_ab: {' '.join(cmd)} failed with exit code {code}:\n{text[-2000:]}")
    times = {}
    for line in text.splitlines():
        m = ROW.match(line)
        if m and m.group(1) not in times:  # the engine's table first, then the broad phase's stages
            times[m.group(1)] = float(m.group(2))
        m = LOOP.search(line)
        if m:
            times["loop"] = float(m.group(1))
    if "loop" not in times:
        sys.exit(f"binary_ab: no 'Loop time' line in the output of {' '.join(cmd)}")
    times["cpu"] = usage.ru_utime + usage.ru_stime
    # Threads going to sleep (voluntary: an idle OpenMP thread at a barrier or between regions
    # with OMP_WAIT_POLICY=PASSIVE) and being taken off a core (involuntary), every thread's.
    times["voluntary_switches"] = float(usage.ru_nvcsw)
    times["involuntary_switches"] = float(usage.ru_nivcsw)
    return times


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("config")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = p.parse_args()
    for path in (args.a, args.b, args.config):
        if not os.path.isfile(path):
            sys.exit(f"binary_ab: {path} does not exist")
    if args.rounds < 1:
        sys.exit("binary_ab: --rounds must be at least 1")
    results = {"A": [], "B": []}
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out.h5")
        for r in range(args.rounds):
            order = [("A", args.a), ("B", args.b)] if r % 2 == 0 else [("B", args.b), ("A", args.a)]
            for label, binary in order:
                load = os.getloadavg()[0]
                t = run(binary, args.config, args.set, out)
                t["load_before"] = load
                results[label].append(t)
                print(f"round {r + 1} {label}: loop {t['loop']:.3f} s, cpu {t['cpu']:.2f} s, "
                      f"{t['voluntary_switches']:.0f} voluntary context switches, load {load:.1f}",
                      flush=True)
    keys = [k for k in results["A"][0] if all(k in t for t in results["A"] + results["B"])]
    print()
    print("| quantity (s, or a count) | A median | A range | B median | B range | B / A |")
    print("| --- | ---: | --- | ---: | --- | ---: |")
    for k in keys:
        a = [t[k] for t in results["A"]]
        b = [t[k] for t in results["B"]]
        ma, mb = statistics.median(a), statistics.median(b)
        ratio = f"{mb / ma:.3f}" if ma > 0 else "-"
        apart = max(a) < min(b) or max(b) < min(a)
        print(f"| {k} | {ma:.3f} | {min(a):.3f}-{max(a):.3f} | {mb:.3f} | {min(b):.3f}-{max(b):.3f} "
              f"| {ratio}{'' if apart else ' (ranges overlap)'} |")
    print(f"\nA = {args.a}\nB = {args.b}\n{args.rounds} rounds, interleaved")


if __name__ == "__main__":
    main()
