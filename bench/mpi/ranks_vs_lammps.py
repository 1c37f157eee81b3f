#!/usr/bin/python3
"""Ours on 2 MPI ranks against LAMMPS on 2 ranks, on the same bed, in the same run (issue 48:
"against LAMMPS at 2 ranks in the same run (goal: still 2x)"); driven by ranks_vs_lammps.sh.

The bed is the LAMMPS side-by-side's settled bed (bench/lammps/side_by_side.sh makes it:
`<dir>/bed_<n>.h5`, our checkpoint, `.data`, the same particles for LAMMPS, `.box`, its walls
and parameters; docs/performance.md "Identical scenes"). Ours runs it with `dem_run` from a config
written here with the side-by-side's law (linear spring k_N in N/m, the dashpot as a coefficient
from LAMMPS's gamma_n, m* = m/2 between spheres and m against a wall, attraction not clipped,
k_T/k_N = 2/7, eta_T/eta_N = 1/2, mu = 0.5, no rotation), its dt and skin; LAMMPS from the
side-by-side's own input (side_by_side.lammps_input). Each round runs, in turn: ours 1 rank x 2
threads, ours 2 ranks x 1 thread (mpirun -np 2 dem_run), LAMMPS 2 ranks (mpirun -np 2 lmp), per
rebuild policy. Timed: ours dem_run's `Loop time` of STEPS steps (it leaves out loading and the
first broad phase), LAMMPS the `Loop time` of its `run STEPS` after a `run 20` warm-up.
Prints each round, the medians, LAMMPS / ours (above 1: ours faster; the goal is 2) and ours
2 ranks / 1 rank x 2 threads (the goal 0.9 of ranks_vs_threads.sh on this bed).
"""
import argparse
import os
import re
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "lammps"))
import side_by_side as sbs  # noqa: E402  (lammps_input, read_box, MPI_ENV)

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_btl_vader_single_copy_mechanism="none", OMP_WAIT_POLICY="PASSIVE")


def our_config(stem, box, policy, steps, path):
    """dem_run's config for the side-by-side scene at `stem` (policy: 0 = when needed, else
    the broad-phase interval)."""
    r = float(box["radius"])
    rho = float(box["density"])
    mass = 4.0 / 3.0 * 3.141592653589793 * r ** 3 * rho
    gn = float(box["gamma_n"])
    kn = float(box["stiffness"])
    dt = float(box["dt"])
    skin = float(box["skin"]) / r  # the side-by-side's skin is in radii (0.5 r)
    law = (f"normal_stiffness: {kn!r}, stiffness_unit: N/m, clip_attractive: false, "
           f"tangential_stiffness_ratio: {2.0 / 7.0!r}, tangential_damping_ratio: 0.5, "
           f"friction: {float(box['friction'])!r}")
    sx, sy, sz = float(box["sx"]), float(box["sy"]), float(box["sz"])
    if sz > 0 or box["gravity"] != "1":
        sys.exit("ranks_vs_lammps: only the side-by-side's beds (no lid, gravity) are run here")
    interval = policy if policy > 0 else 1 << 30
    text = f"""# written by bench/mpi/ranks_vs_lammps.py: the side-by-side bed {os.path.basename(stem)}
scene:
  dt: {dt!r}
  gravity: [0, 0, -9.81]
  broad_phase_interval: {interval}
  skin: {skin!r}
  guard: rebuild
  stability: {{min_steps_per_contact: 15}}
materials:
  grain: {{density: {rho!r}}}
species:
  - {{name: grain, material: grain, radius: {r!r}}}
contact:
  particle_particle: {{{law}, normal_damping: {mass / 2 * gn!r}}}
  particle_wall: {{{law}, normal_damping: {mass * gn!r}}}
walls:
  - {{name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}
  - {{name: x0, type: plane, point: [0, 0, 0], normal: [1, 0, 0]}}
  - {{name: x1, type: plane, point: [{sx!r}, 0, 0], normal: [-1, 0, 0]}}
  - {{name: y0, type: plane, point: [0, 0, 0], normal: [0, 1, 0]}}
  - {{name: y1, type: plane, point: [0, {sy!r}, 0], normal: [0, -1, 0]}}
particles:
  checkpoint: {os.path.abspath(stem + '.h5')}
run:
  duration: {steps * dt!r}
output:
  progress_every: 1000000
"""
    with open(path, "w") as f:
        f.write(text)


def run(cmd, log):
    with open(log, "w") as f:
        res = subprocess.run(cmd, env=ENV, stdout=f, stderr=subprocess.STDOUT)
    text = open(log).read()
    if res.returncode != 0:
        sys.exit(f"ranks_vs_lammps: {' '.join(cmd)} failed (exit {res.returncode}):\n{text[-2000:]}")
    return text


def ours(args, cfg, ranks, threads, tag):
    cmd = ([] if ranks == 1 else ["mpirun", "--oversubscribe", "-np", str(ranks)]) + [
        args.dem, cfg, "--set", f"scene.threads={threads}",
        "--output", os.path.join(args.dir, f"mpi_{tag}.h5")]
    text = run(cmd, os.path.join(args.dir, f"mpi_{tag}.log"))
    m = re.search(r"^Loop time of ([0-9.]+) s for (\d+) steps", text, re.M)
    if not m:
        sys.exit(f"ranks_vs_lammps: no loop time in {args.dir}/mpi_{tag}.log")
    halo = [l.strip() for l in text.splitlines() if re.match(r"\s+\(?rank 0", l)]
    return float(m.group(1)), int(m.group(2)), halo


def lammps(args, stem, box, policy, steps, ranks):
    name = f"mpi_lammps_{ranks}_{policy}"
    path = os.path.join(args.dir, name + ".in")
    with open(path, "w") as f:
        f.write(sbs.lammps_input(os.path.abspath(stem), box, policy, steps=steps))
    cmd = ["mpirun", "--oversubscribe", "-np", str(ranks), "lmp", "-in", path,
           "-log", os.path.join(args.dir, name + ".log"), "-screen", "none"]
    run(cmd, os.path.join(args.dir, name + ".out"))
    log = open(os.path.join(args.dir, name + ".log")).read()
    if "ERROR" in log:
        sys.exit(f"ranks_vs_lammps: LAMMPS failed:\n{log[-2000:]}")
    loops = re.findall(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps", log)
    seconds, procs, nsteps = loops[-1]
    if int(procs) != ranks or int(nsteps) != steps:
        sys.exit(f"ranks_vs_lammps: LAMMPS ran {procs} procs x {nsteps} steps, not {ranks} x {steps}")
    builds = re.findall(r"Neighbor list builds = (\d+)", log)
    return float(seconds), int(builds[-1]) if builds else -1


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--n", type=int, default=150000, help="the side-by-side bed's size")
    p.add_argument("--steps", type=int, default=500)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--policies", default="5,0", help="broad-phase interval, 0 = when needed")
    p.add_argument("--dir", default="results/bench_lammps")
    p.add_argument("--dem", required=True, help="path of dem_run (built with MPI)")
    args = p.parse_args()
    if args.repeats < 1 or args.steps < 1:
        sys.exit("ranks_vs_lammps: --repeats and --steps must be at least 1")
    stem = os.path.join(args.dir, f"bed_{args.n}")
    for ext in (".h5", ".data", ".box"):
        if not os.path.exists(stem + ext):
            sys.exit(f"ranks_vs_lammps: {stem}{ext} missing: make it with "
                     f"bash bench/lammps/side_by_side.sh --sizes {sbs.label(args.n)} --repeats 1")
    box = sbs.read_box(stem + ".box")
    with open("/proc/loadavg") as f:
        print("load average:", " ".join(f.read().split()[:3]), flush=True)
    for policy in (int(x) for x in args.policies.split(",")):
        name = f"every {policy}" if policy else "when needed"
        cfg = os.path.join(args.dir, f"mpi_bed_{args.n}_{policy}.yaml")
        our_config(stem, box, policy, args.steps, cfg)
        t12, t21, tl = [], [], []
        for r in range(args.repeats):
            a, steps, _ = ours(args, cfg, 1, 2, f"{args.n}_{policy}_1x2")
            b, _, halo = ours(args, cfg, 2, 1, f"{args.n}_{policy}_2x1")
            c, builds = lammps(args, stem, box, policy, steps, 2)
            t12.append(a)
            t21.append(b)
            tl.append(c)
            print(f"{name} round {r + 1}: ours 1 rank x 2 threads {a:.3f} s, ours 2 ranks x 1 "
                  f"thread {b:.3f} s, LAMMPS 2 ranks {c:.3f} s ({steps} steps, "
                  f"{sbs.label(args.n)}; LAMMPS {builds} neighbour builds)", flush=True)
        m12, m21, ml = (statistics.median(t) for t in (t12, t21, tl))
        print(f"{name}: medians ours 1x2 {m12:.3f} s, ours 2x1 {m21:.3f} s, LAMMPS 2 ranks "
              f"{ml:.3f} s: LAMMPS / ours at 2 ranks {ml / m21:.2f}x (goal 2), LAMMPS / ours "
              f"1x2 {ml / m12:.2f}x, ours 2 ranks / 1 rank x 2 threads {m12 / m21:.2f}x "
              f"(goal 0.9)")
        for line in halo:
            print("  " + line)
    with open("/proc/loadavg") as f:
        print("load average:", " ".join(f.read().split()[:3]), flush=True)


if __name__ == "__main__":
    main()
