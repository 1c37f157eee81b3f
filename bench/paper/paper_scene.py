"""The paper's scene as a DEM benchmark: the settled 150k pile, the 40,662-triangle bucket on a
prescribed maneuver in three phases, two rebuild policies, 2 threads (docs/performance.md,
"The paper's scene"). Run through bench/paper/paper_scene.sh; not a test."""
import argparse
import math
import os
import re
import subprocess
import sys
import time

import h5py
import numpy as np

CONFIG = "bench/paper/paper_scene.yaml"
PILE = "results/pile_paper.h5"
OUT = "results/paper_bench"

# The maneuver, from the wheel loader's documented co-simulation run (docs/wheel_loader.md):
# (name, forward speed of the A-pin [m/s], vertical speed [m/s], pitch rate [deg/s], curled back
# positive). Penetration: the machine's approach speed with the bucket flat. Tilt: the tilt pulses
# (about 6 deg per 0.6 s pulse) while the slowed machine still pushes. Lift: the boom raises the
# A-pin (1.2 m over 8 s) while the Z-bar keeps curling, the machine nearly stalled.
PHASES = [
    ("penetration", 1.2, 0.0, 0.0),
    ("tilt", 0.3, 0.0, 10.0),
    ("lift", 0.1, 0.15, 4.0),
]
POLICIES = {"every5": {"scene.broad_phase_interval": "5"},
            "needed": {"scene.broad_phase_interval": "1000000", "scene.guard": "rebuild"}}
EDGE_X = 1.65      # cutting edge in the bucket frame (configs/wheel_loader/machine.yaml)
A_PIN_Z = 0.62     # bucket bottom (mesh z min -0.51) 11 cm above the ground: over the bottom layer (r <= 5 cm), which a prescribed bucket would otherwise crush into the floor
LEAD = 0.10        # the edge starts this far in front of the pile's face


def pile_face(path):
    """x of the pile's face at its foot (2nd percentile of x of the grains below 0.5 m)."""
    with h5py.File(path, "r") as f:
        x = f["x"][:]
    low = x[x[:, 2] < 0.5]
    return float(np.percentile(low[:, 0], 2)), len(x)


def write_motion(path, x_face, window):
    x = x_face - LEAD - EDGE_X
    z = A_PIN_Z
    pitch = 0.0
    rows = [(0.0, x, z, pitch)]
    for k, (_, vx, vz, rate) in enumerate(PHASES):
        x += vx * window
        z += vz * window
        pitch += rate * window
        rows.append(((k + 1) * window, x, z, pitch))
    with open(path, "w") as f:
        f.write("time,x,y,z,qw,qx,qy,qz\n")
        for t, x, z, p in rows:
            h = math.radians(p) / 2   # curled back = the bucket's x axis up = about -y
            f.write(f"{t:.6f},{x:.6f},0,{z:.6f},{math.cos(h):.9f},0,{-math.sin(h):.9f},0\n")
    return rows


def parse_table(text):
    out = {}
    m = re.search(r"Loop time of ([\d.]+) s for (\d+) steps with (\d+) particles on (\d+) thread", text)
    if not m:
        return None
    out["wall"], out["steps"], out["n"], out["threads"] = float(m[1]), int(m[2]), int(m[3]), int(m[4])
    for name in ("broad_phase", "pair_forces", "mesh_contacts", "integration", "output", "other"):
        m = re.search(rf"^{name}\s*\|\s*([\d.]+)\s*\|\s*([\d.]+)", text, re.M)
        out[name] = float(m[1]) if m else 0.0
    m = re.search(r"Broad phases: (\d+) \(early rebuilds by the guard: (\d+)"
                  r"(?:; steps its far-mover check spared one: (\d+))?\)", text)
    if not m:
        raise SystemExit("paper_scene.py: dem_run printed no 'Broad phases:' line; see the log")
    out["rebuilds"], out["early"] = int(m[1]), int(m[2])
    out["spared"] = int(m[3]) if m[3] is not None else 0
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    out["rss_kb"] = int(m[1]) if m else 0
    user = re.search(r"User time \(seconds\): ([\d.]+)", text)
    system = re.search(r"System time \(seconds\): ([\d.]+)", text)
    out["cpu_s"] = float(user[1]) + float(system[1]) if user and system else 0.0
    m = re.search(r"Percent of CPU this job got: (\d+)%", text)
    out["cpu"] = int(m[1]) / 100 if m else 0.0   # of the whole process, loading included
    return out


def run_phase(dem_run, policy, k, window, ckpt_in, log):
    name = PHASES[k][0]
    ckpt_out = f"{OUT}/{policy}_{k + 1}_{name}.h5"
    cmd = ["/usr/bin/time", "-v", dem_run, CONFIG,
           "--set", f"run.duration={window}",
           "--set", f"particles.checkpoint={os.path.abspath(ckpt_in)}",
           "--set", f"particles.keep_time={'true' if k > 0 else 'false'}",
           "--set", f"output.checkpoint={ckpt_out}",
           "--set", f"scene.threads={args.threads}",
           "--set", f"tools.0.motion.csv={os.path.abspath(OUT)}/bucket_motion.csv",
           "--output", f"{OUT}/{policy}_{k + 1}_{name}_out.h5"]
    for key, value in POLICIES[policy].items():
        cmd += ["--set", f"{key}={value}"]
    for kv in args.set:
        cmd += ["--set", kv]
    with open(log, "w") as f:
        f.write(" ".join(cmd) + "\n")
        f.flush()
        rc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode
    text = open(log).read()
    if rc != 0:
        sys.exit(f"paper_scene: dem_run failed (exit {rc}) in {policy} / {name}; see {log}:\n"
                 + "\n".join(text.splitlines()[-8:]))
    row = parse_table(text)
    row["policy"], row["phase"], row["sim"] = policy, name, window
    return row, ckpt_out


def load():
    return " ".join(open("/proc/loadavg").read().split()[:3])


parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--dem-run", default="build/bin/dem_run")
parser.add_argument("--window", type=float, default=0.3,
                    help="simulated seconds per phase (default 0.3)")
parser.add_argument("--policies", default="every5,needed")
parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="extra dem_run --set for every window, e.g. scene.sleep.enabled=true")
parser.add_argument("--threads", type=int, default=2)
parser.add_argument("--out", default=OUT, help="folder for logs, checkpoints, the motion CSV")
parser.add_argument("--config", default=CONFIG, help=argparse.SUPPRESS)   # for testing the script
parser.add_argument("--repeats", type=int, default=1,
                    help="whole maneuvers per policy, interleaved (policy order reversed every "
                         "other repeat); the summary gives the median and range (default 1)")
parser.add_argument("--pile", default=PILE,
                    help="settled pile checkpoint (default results/pile_paper.h5)")
args = parser.parse_args()
if args.repeats < 1:
    parser.error(f"--repeats {args.repeats}: give at least 1")
if args.window <= 0:
    parser.error(f"--window {args.window}: give a positive number of simulated seconds")
if not os.path.isfile(args.pile):
    parser.error(f"--pile {args.pile}: no such file (prepare one with bench/paper/prepare_pile.sh; "
                 "--compact gives results/pile_paper_compacted.h5)")
policies = args.policies.split(",")
for p in policies:
    if p not in POLICIES:
        parser.error(f"--policies: unknown policy {p!r}; use a comma-separated list of "
                     + ", ".join(POLICIES))
CONFIG, PILE, OUT = args.config, args.pile, args.out

os.makedirs(OUT, exist_ok=True)
x_face, n = pile_face(PILE)
rows = write_motion(f"{OUT}/bucket_motion.csv", x_face, args.window)
print(f"paper_scene: {n} particles from {PILE}, face at x = {x_face:.2f} m; bucket_r4 (40,662 "
      f"triangles); dt 1e-4 s; {args.threads} threads; window {args.window} s per phase")
print("maneuver (A-pin x, z [m], pitch [deg] at the phase ends): "
      + "; ".join(f"t {t:.2f}: {x:.2f}, {z:.2f}, {p:.1f}" for t, x, z, p in rows))
print(f"load average at start: {load()}")
sys.stdout.flush()
results = []
for rep in range(args.repeats):
    # Interleaved: a machine whose speed drifts between minutes hits every policy alike.
    for policy in (policies if rep % 2 == 0 else policies[::-1]):
        ckpt = PILE
        for k in range(len(PHASES)):
            t0 = time.time()
            row, ckpt = run_phase(args.dem_run, policy, k, args.window, ckpt,
                                  f"{OUT}/{policy}_{k + 1}_{PHASES[k][0]}.log")
            row["repeat"] = rep + 1
            results.append(row)
            print(f"  {'repeat ' + str(rep + 1) + ' ' if args.repeats > 1 else ''}{policy:7s} "
                  f"{row['phase']:12s} RTF {row['wall'] / row['sim']:7.1f}  "
                  f"({time.time() - t0:.0f} s wall with loading)")
            sys.stdout.flush()

print(f"\nload average at end: {load()}")
print("\n| policy | repeat | phase | simulated (s) | wall (s) | real-time factor | broad phase % | "
      "mesh contacts % | rebuilds (early; spared by the far-mover check) | CPU share (cores) | peak RSS (MB) | bytes/particle |")
print("| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for r in results:
    rss = r["rss_kb"] * 1024
    print(f"| {'every 5 steps' if r['policy'] == 'every5' else 'when needed'} | {r['repeat']} | {r['phase']} | "
          f"{r['sim']:.3f} | {r['wall']:.1f} | {r['wall'] / r['sim']:.0f} | "
          f"{100 * r['broad_phase'] / r['wall']:.0f} | {100 * r['mesh_contacts'] / r['wall']:.0f} | "
          f"{r['rebuilds']} ({r['early']}; {r['spared']}) | {r['cpu']:.2f} | {rss / 2**20:.0f} | {rss / r['n']:.0f} |")
for policy in policies:
    rtf, cpu = [], []
    for rep in range(1, args.repeats + 1):
        rs = [r for r in results if r["policy"] == policy and r["repeat"] == rep]
        wall, sim = sum(r["wall"] for r in rs), sum(r["sim"] for r in rs)
        rtf.append(wall / sim)
        # CPU seconds of the processes (loading included) per simulated second: the work,
        # steadier than the wall time where a stalled vCPU stalls the other thread's barrier.
        cpu.append(sum(r["cpu_s"] for r in rs) / sim)
        if args.repeats == 1:
            print(f"{policy}: whole maneuver {sim:.2f} s simulated in {wall:.0f} s wall, real-time "
                  f"factor {wall / sim:.0f}; CPU {cpu[-1]:.0f} core-s per simulated s")
    if args.repeats > 1:
        print(f"{policy}: whole maneuver, {args.repeats} repeats: real-time factor median "
              f"{np.median(rtf):.0f} (range {min(rtf):.0f}-{max(rtf):.0f}; "
              + ", ".join(f"{x:.0f}" for x in rtf) + f"); CPU median {np.median(cpu):.0f} "
              f"core-s per simulated s (range {min(cpu):.0f}-{max(cpu):.0f})")
