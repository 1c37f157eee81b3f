#!/usr/bin/python3
"""The hauler's first seconds of tipping over several preparations of its load, with each particle
model (docs/hauler.md "The load before and after", docs/soil_models.md "Which scene needs which").

    /usr/bin/python3 bench/soil/hauler_preparations.py [--models translating,rotating]
        [--seeds 5,6,7] [--end 3] [--out results/hauler_preparations] [--build build]
        [--threads 2] [--prepare-only] [--analyse-only] [--fresh]

For each model and insertion seed S it prepares the load in the dump body with the model's two
stages (`nice dem_run`; --set particles.insert.0.seed=S, the checkpoints into --out):

  translating  configs/soil/hauler_load_prepare.yaml + hauler_load_release.yaml, run with
               configs/hauler.yaml (configs/materials/dry_sand.yaml)
  rotating     configs/soil/hauler_load_rotating_prepare.yaml + _release.yaml, run with
               configs/hauler_rotating.yaml (configs/materials/dry_sand_rotating.yaml)

prints the `Prepared bed:` line (packing fraction, bulk density, coordination 2 diameters inside
the flat bed) and the load that stays, computes the load's static_load (mass, centre of gravity,
radius of gyration in the body frame at the pose the load was prepared at, the shipped one), then
runs `nice cosim_master SCENE` up to --end seconds on that load (dem_service launched with
`--set particles.checkpoint=`) with its static_load, the soil's
particle snapshots every 0.02 s and every grain perturbed by 1e-6 m (seed 1), as
scripts/hauler_models.py's members. The analysis is scripts/hauler_models.py's `analyse()`: over
0.5 s windows the soil's torque on the body about the hinge against what the load's weight and
momentum give, and the front axle's vertical force (0.05 s moving average). Printed: per
preparation, then mean +- 95 % t-interval over the preparations for each model (the excess per
window, the front axle at 1 and 2 s and its gain from 1 to 2 s), and with two models their
difference with a Welch 95 % interval. The numbers go to OUT/summary.csv too. A complete output
is reused unless --fresh.
"""
import argparse
import csv
import math
import os
import re
import subprocess
import sys

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from hauler_models import analyse  # noqa: E402  (the same analysis as the models' comparison)

MODELS = {
    "translating": ("configs/soil/hauler_load_prepare.yaml", "configs/soil/hauler_load_release.yaml",
                    "configs/hauler.yaml", "configs/soil/hauler_load.yaml"),
    "rotating": ("configs/soil/hauler_load_rotating_prepare.yaml",
                 "configs/soil/hauler_load_rotating_release.yaml", "configs/hauler_rotating.yaml",
                 "configs/soil/hauler_load_rotating.yaml"),
}
# t quantiles, two-sided 95 %
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228}


def t95(dof):
    if dof in T95:
        return T95[dof]
    if dof > 10:
        try:
            from scipy.stats import t
            return float(t.ppf(0.975, dof))
        except ImportError:
            return 1.96 + 2.4 / dof  # within 1 % of t for dof > 10
    # Welch's fractional degrees of freedom below 10: interpolate between the integers
    lo = max(1, int(math.floor(dof)))
    hi = lo + 1
    return T95[lo] + (T95.get(hi, T95[10]) - T95[lo]) * (dof - lo)


def mean_ci(values):
    v = np.asarray(values, float)
    if len(v) < 2:
        return float(v.mean()), float("nan"), float("nan")
    sd = float(v.std(ddof=1))
    return float(v.mean()), t95(len(v) - 1) * sd / math.sqrt(len(v)), sd


def welch(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    se = math.sqrt(va + vb)
    dof = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1)) if se > 0 else 1e9
    return float(b.mean() - a.mean()), t95(dof) * se


def rotation(q):
    w, a, b, c = q
    return np.array([[1 - 2 * (b * b + c * c), 2 * (a * b - c * w), 2 * (a * c + b * w)],
                     [2 * (a * b + c * w), 1 - 2 * (a * a + c * c), 2 * (b * c - a * w)],
                     [2 * (a * c - b * w), 2 * (b * c + a * w), 1 - 2 * (a * a + b * b)]])


def start_pose(prepare_cfg):
    """The body's pose the load is prepared at: the single keyframe of the prepare config."""
    text = open(os.path.join(ROOT, prepare_cfg)).read()
    m = re.search(r"- \{time: 0\.0, position: \[(.*?)\], orientation: \[(.*?)\]\}", text)
    if not m:
        sys.exit(f"hauler_preparations: {prepare_cfg} has no single start keyframe")
    pos = [float(x) for x in m.group(1).split(",")]
    quat = [float(x) for x in m.group(2).split(",")]
    return np.array(pos), np.array(quat)


def static_load(load_h5, pose):
    """Mass, centre of gravity (x, z) and radius of gyration about y in the body frame."""
    with h5py.File(load_h5, "r") as f:
        x = f["x"][:].reshape(-1, 3)
        m = f["mass"][:]
    local = (x - pose[0]) @ rotation(pose[1])
    com = (local * m[:, None]).sum(0) / m.sum()
    gyr = math.sqrt(((local[:, 0] - com[0]) ** 2 + (local[:, 2] - com[2]) ** 2) @ m / m.sum())
    return len(m), float(m.sum()), (float(com[0]), float(com[2])), gyr


def run(cmd, log):
    print("hauler_preparations:", " ".join(cmd), flush=True)
    with open(log, "w") as f:
        r = subprocess.run(["nice"] + cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT)
    if r.returncode != 0:
        sys.exit(f"hauler_preparations: failed ({r.returncode}), see {log}:\n" + open(log).read()[-3000:])
    return open(log).read()


def prepare(model, seed, a):
    prep, release = MODELS[model][:2]
    name = os.path.join(a.out, f"{model}_{seed}")
    bed, load = name + "_bed.h5", name + "_load.h5"
    if a.analyse_only and not os.path.exists(load):
        sys.exit(f"hauler_preparations: --analyse-only: {load} is missing; run without --analyse-only first")
    if a.fresh or not os.path.exists(load):
        dem_run = os.path.join(a.build, "bin/dem_run")
        run([dem_run, prep, "--set", f"particles.insert.0.seed={seed}", "--set", f"prepare.checkpoint={bed}",
             "--set", f"output.file={name}_prepare.h5", "--set", f"scene.threads={a.threads}"], name + "_prepare.log")
        run([dem_run, release, "--set", f"particles.checkpoint={bed}", "--set", f"settle.checkpoint={load}",
             "--set", f"output.file={name}_release.h5", "--set", f"scene.threads={a.threads}"], name + "_release.log")
    lines = (open(name + "_prepare.log").read() + open(name + "_release.log").read()).splitlines()
    bed_line = next((ln for ln in lines if ln.startswith("Prepared bed:")), "Prepared bed: (not printed)")
    settle = next((ln for ln in lines if ln.startswith("settle:")), "settle: (not printed)")
    return bed_line, settle, load


def tip(model, seed, load, static, a):
    scene, soil = MODELS[model][2:]
    out = os.path.join(a.out, f"{model}_{seed}")
    done = os.path.exists(out + ".h5") and os.path.exists(out + "_soil.h5")
    if done and not a.fresh:
        with h5py.File(out + ".h5", "r") as f:
            done = len(f["time"]) > 0 and f["time"][-1] >= a.end - 2e-3
    if a.analyse_only and not done:
        sys.exit(f"hauler_preparations: --analyse-only: {out}.h5 is missing or shorter than --end {a.end}; "
                 "run without --analyse-only first")
    if a.fresh or not done:
        sets = [f"time.end={a.end}", f"output.file={out}.h5", f"output.csv={out}.csv", "output.progress=off",
                f"participants.hauler.parameters.static_load={static}",
                # dem_service loads its checkpoint when it starts, before the master's parameters
                f"participants.soil.launch=[dem_service, {os.path.join(ROOT, soil)}, --set, "
                f"particles.checkpoint={load}, --set, scene.threads={a.threads}]",
                f"participants.soil.parameters.output.file={out}_soil.h5",
                "participants.soil.parameters.output.particles_every=0.02",
                "participants.soil.parameters.particles.perturb.amplitude=1.0e-6",
                "participants.soil.parameters.particles.perturb.seed=1",
                f"bus.url=udpm://239.255.76.67:{7600 + (os.getpid() + seed) % 300}?ttl=0"]
        cmd = [os.path.join(a.build, "bin/cosim_master"), scene]
        for s in sets:
            cmd += ["--set", s]
        run(cmd, out + ".log")
    return analyse(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", default="translating,rotating")
    ap.add_argument("--seeds", default="5,6,7")
    ap.add_argument("--end", type=float, default=3.0)
    ap.add_argument("--out", default=os.path.join(ROOT, "results/hauler_preparations"))
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--threads", type=int, default=2, help="the DEM's threads (preparation and tipping)")
    ap.add_argument("--prepare-only", action="store_true")
    ap.add_argument("--analyse-only", action="store_true", help="reuse every output; run nothing")
    ap.add_argument("--fresh", action="store_true")
    a = ap.parse_args()
    a.out, a.build = os.path.abspath(a.out), os.path.abspath(a.build)
    models = a.models.split(",")
    for m in models:
        if m not in MODELS:
            sys.exit(f"hauler_preparations: --models: unknown model '{m}' (translating, rotating)")
    try:
        seeds = [int(s) for s in a.seeds.split(",")]
    except ValueError:
        sys.exit(f"hauler_preparations: --seeds {a.seeds}: give whole numbers separated by commas, e.g. 5,6,7")
    if a.threads < 1:
        sys.exit(f"hauler_preparations: --threads {a.threads}: at least 1")
    if not a.end > 1.5:
        sys.exit(f"hauler_preparations: --end {a.end}: the body rises from 1 s; give at least 2 s")
    os.makedirs(a.out, exist_ok=True)
    if a.analyse_only:
        a.fresh = False
    results = {}
    for model in models:
        pose = start_pose(MODELS[model][0])
        for seed in seeds:
            bed_line, settle, load = prepare(model, seed, a)
            n, mass, com, gyr = static_load(load, pose)
            static = f"{{mass: {mass:.1f}, com: [{com[0]:.3f}, {com[1]:.3f}], gyration_radius: {gyr:.2f}}}"
            print(f"\n{model}, seed {seed}: {bed_line}\n  {settle}\n  load {n} grains, {mass / 1e3:.2f} t, "
                  f"static_load {static}", flush=True)
            if a.prepare_only:
                continue
            rows, front = tip(model, seed, load, static, a)
            results.setdefault(model, []).append((seed, n, mass, rows, front))
            print("  window [s]: soil torque / weight + momentum [kN m] (excess): " + "; ".join(
                f"{r[0]:.2f}-{r[1]:.2f}: {r[2] / 1e3:.1f} / {r[3] / 1e3:.1f} ({100 * (r[2] / r[3] - 1):+.2f} %)"
                for r in rows))
            print("  front axle F_z [kN]: " + ", ".join(f"{t:.1f} s {v / 1e3:.1f}" for t, v in sorted(front.items())),
                  flush=True)
    if a.prepare_only or not results:
        return
    # summary: per model the mean +- 95 % t-interval over the preparations
    table = []  # (outcome, {model: values})
    first = results[models[0]][0][3]
    table.append(("load in the body [t]", {m: [r[2] / 1e3 for r in results[m]] for m in results}))
    for k, row in enumerate(first):
        table.append((f"soil torque about the hinge, {row[0]:.1f}-{row[1]:.1f} s [kN m]",
                      {m: [r[3][k][2] / 1e3 for r in results[m]] for m in results}))
        table.append((f"weight + momentum, {row[0]:.1f}-{row[1]:.1f} s [kN m]",
                      {m: [r[3][k][3] / 1e3 for r in results[m]] for m in results}))
        table.append((f"excess over weight + momentum, {row[0]:.1f}-{row[1]:.1f} s [%]",
                      {m: [100 * (r[3][k][2] / r[3][k][3] - 1) for r in results[m]] for m in results}))
    for t in sorted(results[models[0]][0][4]):
        table.append((f"front axle F_z at {t:.1f} s [kN]", {m: [r[4][t] / 1e3 for r in results[m]] for m in results}))
    if all(1.0 in r[4] and 2.0 in r[4] for m in results for r in results[m]):
        table.append(("front axle gain, 1 s to 2 s [kN]",
                      {m: [(r[4][2.0] - r[4][1.0]) / 1e3 for r in results[m]] for m in results}))
    print(f"\nmean +- 95 % t-interval over the preparations (seeds {a.seeds})" +
          (f"; the difference {models[1]} - {models[0]} with a Welch 95 % interval" if len(results) == 2 else ""))
    head = "| outcome | " + " | ".join(f"{m} ({len(results[m])} preparations)" for m in results) + \
        (" | difference |" if len(results) == 2 else " |")
    print(head)
    print("| --- |" + " ---: |" * (len(results) + (1 if len(results) == 2 else 0)))
    with open(os.path.join(a.out, "summary.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["outcome", "model", "mean", "ci95", "sd", "values"])
        for name, per in table:
            cells = []
            for m in results:
                mu, ci, sd = mean_ci(per[m])
                cells.append(f"{mu:.2f} +- {ci:.2f}")
                w.writerow([name, m, f"{mu:.4f}", f"{ci:.4f}", f"{sd:.4f}", " ".join(f"{v:.4f}" for v in per[m])])
            if len(results) == 2 and all(len(per[m]) > 1 for m in results):
                d, ci = welch(per[models[0]], per[models[1]])
                cells.append(f"{d:+.2f} +- {ci:.2f}")
            print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
