#!/usr/bin/python3
"""Blade against earthmoving theory (docs/soil_blade.md), one command.

A wide straight blade is pushed at a constant speed through a plane-strain bin of a random
packing (smooth side walls, a rough floor), at two depths and two rake angles. Its horizontal
draft force over the steady part of the travel is compared with Reece's equation (the passive
wedge N_gamma of `soil_wedge`, dem_service/src/earthmoving.cpp) for the friction angle that the
project's own triaxial test (`dem_lab triaxial`) measures on the same grains and particle law,
and for the soil-blade friction angle delta = atan(blade friction).

    /usr/bin/python3 bench/soil/blade_validation.py [--out results/blade] [--build build]
        [--seeds 2] [--jobs 2] [--rate-check] [--skim 1.0] [--speed 0.02]
        [--depths 0.04,0.06] [--rakes 90,45] [--bin-length 0.28] [--bed-height 0.09]
        [--material configs/materials/dry_sand.yaml] [--model translating|rotating]
        [--rolling-friction 0.1] [--rolling-damping 0.3] [--blade-friction 0.2]
        [--test triaxial|biaxial] [--lab-seeds 1]

Without --material the soil is the study's own (1 cm grains, mu 0.2, GRAIN and LAW below). With
--material the grains (density, radius), the particle law and the deposition friction of the bed
come from that material file, and every length of the scene (bin, bed, depths, travel, blade,
skim) is the same number of mean grain diameters D as the default scene's with its 1 cm grains;
lengths on the command line are metres, or mean diameters with a trailing D ("4D,6D"). The
default speed keeps the inertial number of the default scene (0.02 m/s x sqrt(D / 1 cm)) and dt
is 0.85 of the engine's largest safe step for the law and model (asked from dem_run).
--model rotating runs the cases with spheres that rotate (6 DOF) and the EPSD rolling
resistance; the bed is prepared (and shared) by the translating model, and the triaxial test is
run with the same model (dem_lab must know `grains.model`, or --phi gives the angle).

--test biaxial takes the friction angle from `dem_lab biaxial` (plane strain, the blade's own
deformation: Reece's wedge is a plane analysis) instead; the table and chart then carry
`_biaxial` in their names. --lab-seeds N runs the lab test on N samples (seeds) and takes the
mean of their fits (sample 1 is the single-sample run's, reused).

Steps (each skipped when its output exists, made from the same config, and --fresh is not
given):
  1. triaxial: dem_lab triaxial bench/soil/blade_triaxial.yaml (the blade's law) -> phi
     (or dem_lab biaxial bench/soil/blade_biaxial.yaml)
  2. beds: one prepared bed per seed (random insertion, frictionless deposition, frozen with
     the law's friction), configs written to OUT/bed_s<seed>.yaml
  3. cases: per seed, depth and rake, a dem_run config OUT/case_*.yaml loading the bed, with
     the blade's mesh (two triangles, generated into OUT/meshes/) moving at --speed
  4. table (stdout and OUT/blade_summary.csv) and chart OUT/blade_validation.png

The soil that rises more than `--skim` grain diameters above the bed's surface is taken away
(`scene.region`): Reece's gamma term is the blade without a surcharge, and without the skim the
heap in front of the blade grows with the travel and the force never levels off.
"""
import argparse
import csv
import math
import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

# --- the soil (one place: the triaxial config must hold the same grains and law) ----------
GRAIN = dict(density=2600.0, r_min=0.0045, r_max=0.0055)
LAW = dict(normal_stiffness=1.0e4, stiffness_unit="N/m", restitution=0.3,
           tangential_stiffness_ratio=0.5, tangential_damping_ratio=0.5, friction=0.2)
BLADE_FRICTION = 0.2          # soil-blade mu: delta = atan(0.2) = 11.3 deg (about phi / 3)
DT = 3.0e-5                   # s; the engine checks it against the contact period (largest safe 3.5e-5)
G = 9.81
MATERIAL = None               # the material file (absolute path) when --material is given
DEPOSITION_FRICTION = 0.0     # of the bed's fall (the material's with --material)
MODEL = "translating"         # particles.model of the cases and the triaxial test
BED_DT = DT                   # dt of the bed's preparation (the translating model's)
ROLLING = dict(friction=0.1, damping=0.3)   # EPSD rolling resistance of the rotating model
D_REF = 0.01                  # m: the mean diameter the default scene's lengths are written for
SCALE = 1.0                   # D / D_REF
CONFINING = [1.0e3, 2.0e3, 4.0e3]   # Pa: the triaxial test's sigma_3 (the wedge's 1-4 kPa)

# --- the bin (plane strain: thin in y, smooth side walls) ---------------------------------
BIN_L, BIN_W = 0.28, 0.04     # m: length along the travel, thickness (4 mean diameters)
BED_H = 0.09                  # m: target bed height (the deepest cut leaves 3 D below the tip)
DEPTHS = [0.04, 0.06]          # m: 4 and 6 mean grain diameters
RAKES = [90.0, 45.0]          # deg from the horizontal
TRAVEL = 0.08                 # m of blade travel
STEADY_FROM = 0.04            # m: the steady window is [STEADY_FROM, TRAVEL] of travel
REACH = 0.06                  # m: the blade reaches this far above the surface


def law_yaml(law, indent):
    pad = " " * indent
    return "".join(f"{pad}{k}: {v}\n" for k, v in law.items())


def mean_grain_volume():
    a, b = GRAIN["r_min"], GRAIN["r_max"]
    r3 = (b ** 4 - a ** 4) / (4 * (b - a))
    return 4.0 / 3.0 * math.pi * r3


def walls_yaml():
    smooth = "{friction: 0.0}"
    return (
        "walls:\n"
        f"  - {{name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}\n"
        f"  - {{name: back, type: plane, point: [0, 0, 0], normal: [1, 0, 0], contact: {smooth}}}\n"
        f"  - {{name: front, type: plane, point: [{BIN_L}, 0, 0], normal: [-1, 0, 0], contact: {smooth}}}\n"
        f"  - {{name: side0, type: plane, point: [0, 0, 0], normal: [0, 1, 0], contact: {smooth}}}\n"
        f"  - {{name: side1, type: plane, point: [0, {BIN_W}, 0], normal: [0, -1, 0], contact: {smooth}}}\n")


def head_yaml(threads=1, region_top=None, dt=None):
    s = ("scene:\n"
         f"  dt: {dt or DT}\n"
         "  gravity: [0, 0, -9.81]\n"
         "  broad_phase_interval: 5\n"
         "  skin: 0.5\n"
         f"  threads: {threads}\n")
    if region_top is not None:
        s += f"  region: {{min: [-1, -1, -1], max: [{BIN_L + 1}, {BIN_W + 1}, {region_top:.6f}]}}\n"
    if MATERIAL:
        # density, radius and the particle law from the file (docs/soil.md "Material files")
        s += ("materials:\n"
              f"  sand: {{file: {MATERIAL}}}\n"
              "species:\n"
              "  - {name: grain, material: sand}\n")
    else:
        s += ("materials:\n"
              f"  sand: {{density: {GRAIN['density']}}}\n"
              "species:\n"
              "  - name: grain\n"
              "    material: sand\n"
              f"    radius: {{distribution: uniform, min: {GRAIN['r_min']}, max: {GRAIN['r_max']}}}\n"
              "contact:\n"
              "  particle_particle:\n" + law_yaml(LAW, 4))
    return s


def tag():
    """Suffix of the files of the rotating model's runs (the translating one keeps the old names)."""
    return "" if MODEL == "translating" else "_rot"


def lab_tag():
    """Suffix of the table and chart whose theory takes the biaxial (plane-strain) angle."""
    return "" if ARGS.test == "triaxial" else "_" + ARGS.test


def model_yaml():
    """particles.model lines of a case (nothing for the default translating model)."""
    if MODEL == "translating":
        return ""
    return ("  model: rotating\n"
            f"  rolling_resistance: {{model: epsd, friction: {ROLLING['friction']}, "
            f"damping: {ROLLING['damping']}}}\n")


def bed_config(seed, out):
    n = int(round(0.63 * BIN_L * BIN_W * BED_H / mean_grain_volume()))
    top = BED_H * 0.63 / 0.27   # insertion at a solid fraction of 0.27 (at most 0.3 allowed)
    # The translating model's dt: one bed serves both models (a rotating scene loads a bed
    # saved without spins at rest).
    return n, (head_yaml(dt=BED_DT) + walls_yaml() +
               "particles:\n  insert:\n"
               f"    - {{species: grain, min: [0, 0, 0], max: [{BIN_L}, {BIN_W}, {top:.4f}], count: {n}, seed: {seed}}}\n"
               "prepare:\n" +
               ("" if MATERIAL else "  deposition_friction: 0.0\n") +
               f"  ke_per_particle: {1.0e-7 * SCALE ** 4:.6g}\n"
               f"  max_time: {3.0 * math.sqrt(SCALE):.6g}\n"
               "  margin: 1.0\n"
               f"  checkpoint: bed_s{seed}.h5\n"
               "run:\n  duration: 0\n"
               f"output:\n  file: bed_s{seed}_run.h5\n  progress_every: 30\n")



def blade_mesh(path, rake_deg, length):
    """Two triangles: the blade's tip line along y at the origin, the blade leaning back
    (towards -x) at the rake angle from the horizontal; wider than the bin by 5 mm a side."""
    a = math.radians(rake_deg)
    tx, tz = -length * math.cos(a), length * math.sin(a)
    y0, y1 = -0.5 * D_REF * SCALE, BIN_W + 0.5 * D_REF * SCALE
    with open(path, "w") as f:
        f.write("# generated by bench/soil/blade_validation.py\n")
        for v in [(0, y0, 0), (0, y1, 0), (tx, y1, tz), (tx, y0, tz)]:
            f.write("v %.6f %.6f %.6f\n" % v)
        f.write("f 1 2 3\nf 1 3 4\n")


def case_config(out, seed, depth, rake, surface, speed, skim):
    name = f"case_s{seed}_d{int(round(depth * 1000))}_a{int(rake)}" + ("" if speed == ARGS.speed else f"_v{speed:g}") + tag()
    mesh = f"meshes/blade_a{int(rake)}.obj"
    length = (depth + REACH) / math.sin(math.radians(rake))   # reaches REACH above the surface
    blade_mesh(os.path.join(out, mesh), rake, length)
    ztip = surface - depth
    dur = TRAVEL / speed
    region_top = surface + skim * (GRAIN["r_min"] + GRAIN["r_max"])
    txt = (head_yaml(region_top=region_top) + walls_yaml() +
           "tools:\n"
           "  - name: blade\n"
           f"    mesh: {mesh}\n"
           f"    contact: {{friction: {BLADE_FRICTION}}}\n"
           "    motion:\n"
           "      interpolation: linear\n"
           "      keyframes:\n"
           f"        - {{time: 0.0, position: [0.0, 0.0, {ztip:.6f}], orientation: [1, 0, 0, 0]}}\n"
           f"        - {{time: {dur:.6f}, position: [{TRAVEL}, 0.0, {ztip:.6f}], orientation: [1, 0, 0, 0]}}\n"
           f"particles:\n  checkpoint: bed_s{seed}.h5\n" + model_yaml() +
           f"run:\n  duration: {dur:.6f}\n"
           f"output:\n  file: {name}.h5\n  particles_every: {dur / 4:.6f}\n"
           f"  wrenches_every: {max(DT, 0.001 * D_REF * SCALE / speed):.6g}\n  progress_every: 60\n")
    return name, os.path.join(out, name + ".yaml"), txt


def same_config(path, txt):
    """True when path holds exactly txt (a result made from it can be reused)."""
    try:
        with open(path) as f:
            return f.read() == txt
    except OSError:
        return False


def run(cmd, log, cwd=None):
    with open(log, "w") as f:
        r = subprocess.run(["nice"] + cmd, stdout=f, stderr=subprocess.STDOUT, cwd=cwd)
    if r.returncode != 0:
        sys.exit(f"blade_validation: {' '.join(cmd)} failed ({r.returncode}); see {log}")


def triaxial(out, build):
    """The friction angle for the theory: `dem_lab triaxial` (or `biaxial` with --test biaxial,
    the plane-strain angle) on the blade's grains, one sample per --lab-seeds. Returns the mean
    over the samples of the Mohr-Coulomb fit through the origin and, per confining pressure,
    the samples' mean peak angle, axial strain and inner packing."""
    name = ARGS.test
    cfg = os.path.join(os.path.dirname(os.path.abspath(__file__)), f"blade_{name}.yaml")
    sets = [f"grains.contact.{k}={v}" for k, v in LAW.items()]
    sets += [f"grains.density={GRAIN['density']}",
             f"grains.radius={{min: {GRAIN['r_min']}, max: {GRAIN['r_max']}}}",
             f"sample.preparation_friction={DEPOSITION_FRICTION}",
             f"{name}.confining_pressures=[" + ", ".join(f"{p:g}" for p in CONFINING) + "]"]
    if MATERIAL:
        # the material's samples (compacted with its deposition friction, looser than the
        # default study's frictionless ones) peak late: to 15 % axial strain
        sets.append(f"{name}.max_axial_strain=0.15")
    if MODEL != "translating":
        sets += [f"grains.model={MODEL}",
                 f"grains.rolling_resistance={{model: epsd, friction: {ROLLING['friction']}, "
                 f"damping: {ROLLING['damping']}}}"]
    if ARGS.phi is not None:
        return ARGS.phi, [(CONFINING[0], ARGS.phi, float("nan"), float("nan"))]
    fits, pers = [], []
    for seed in range(1, ARGS.lab_seeds + 1):
        # seed 1 is the config's own sample (the folder and stamp of a single-sample run)
        sfx = "" if seed == 1 else f"_s{seed}"
        seed_sets = sets + ([f"sample.seed={seed}"] if seed > 1 else [])
        tri_dir = os.path.join(out, name + tag() + sfx)
        fit = os.path.join(tri_dir, f"{name}_summary.csv")
        cmd = [ARGS.lab or os.path.join(build, "bin", "dem_lab"), name, cfg, "--out",
               tri_dir, "--no-plot"] + sum([["--set", x] for x in seed_sets], [])
        stamp = os.path.join(out, f"{name}{tag()}{sfx}.cmd")   # the test's inputs (not its output folder)
        what = " ".join([name, cfg] + seed_sets) + "\n"
        if ARGS.fresh or not os.path.exists(fit) or not same_config(stamp, what):
            print(f"{name}: dem_lab {name}", cfg, f"(sample {seed})", flush=True)
            run(cmd, os.path.join(out, f"{name}{tag()}{sfx}.log"))
            with open(stamp, "w") as f:
                f.write(what)
        rows = list(csv.DictReader(open(fit)))
        s3 = np.array([float(r["sigma3_peak_Pa"]) for r in rows])
        s1 = np.array([float(r["sigma1_peak_Pa"]) for r in rows])
        # Mohr-Coulomb through the origin (cohesionless): sin phi = sum(s t) / sum(s^2).
        s, t = (s1 + s3) / 2, (s1 - s3) / 2
        fits.append(math.degrees(math.asin(float(np.sum(s * t) / np.sum(s * s)))))
        pers.append([(float(r["confining_Pa"]), float(r["phi_peak_deg"]), float(r["peak_axial_strain"]),
                      float(r["packing_inner"])) for r in rows])
    if len(fits) > 1:
        sd = float(np.std(fits, ddof=1))
        print(f"{name}: {len(fits)} samples, through the origin " + ", ".join(f"{f:.2f}" for f in fits) +
              f" deg: mean {np.mean(fits):.2f}, sd {sd:.2f}, 95 % interval of the mean +- "
              f"{T95[len(fits) - 1] * sd / math.sqrt(len(fits)):.2f} deg", flush=True)
    per = [tuple(float(np.mean([p[i][j] for p in pers])) for j in range(4)) for i in range(len(pers[0]))]
    return float(np.mean(fits)), per


T95 = {1: 12.71, 2: 4.30, 3: 3.18, 4: 2.78, 5: 2.57, 6: 2.45, 7: 2.36, 8: 2.31, 9: 2.26}


def bed_measures(h5):
    import h5py
    with h5py.File(h5, "r") as f:
        a = dict(f["/bed"].attrs)
        pos, rad = f["x"][()], f["radius"][()]   # a State checkpoint (dem/checkpoint.hpp)
    # Surface: the highest grain top in each column one mean diameter wide along x (away from
    # the end walls), averaged.
    tops = []
    dm = GRAIN["r_min"] + GRAIN["r_max"]
    for x0 in np.arange(2 * dm, BIN_L - 2 * dm, dm):
        m = (pos[:, 0] >= x0) & (pos[:, 0] < x0 + dm)
        if m.any():
            tops.append(float(np.max(pos[m, 2] + rad[m])))
    # Bulk density of the whole bin width (the wedge's weight includes the grains the side walls
    # order): the grains with their centre in the slab from 2 diameters above the floor to 2
    # below the surface, over the bin's whole length and width.
    surface = float(np.mean(tops))
    d = GRAIN["r_min"] + GRAIN["r_max"]
    z1, z2 = 2 * d, surface - 2 * d
    m = (pos[:, 2] >= z1) & (pos[:, 2] < z2)
    slab = float(np.sum(4.0 / 3.0 * np.pi * rad[m] ** 3)) / (BIN_L * BIN_W * (z2 - z1))
    return dict(packing=float(a["packing_fraction"]), inner_density=float(a["bulk_density"]),
                slab_packing=slab, density=slab * GRAIN["density"],
                coordination=float(a["coordination"]), grains=len(pos),
                surface=surface, surface_sd=float(np.std(tops)))


def wedge(build, phi, delta, rake, gamma, depth, width):
    r = subprocess.run([os.path.join(build, "bin", "soil_wedge"), "--phi", f"{phi}", "--delta",
                        f"{delta}", "--alpha", f"{rake}", "--gamma", f"{gamma}", "--depth",
                        f"{depth}", "--width", f"{width}"], capture_output=True, text=True, check=True)
    m = re.search(r"draft force ([0-9.eE+-]+) N", r.stdout)
    ng = re.search(r"N_gamma ([0-9.eE+-]+)", r.stdout)
    beta = re.search(r"failure plane at ([0-9.eE+-]+) deg", r.stdout)
    return float(m.group(1)), float(ng.group(1)), float(beta.group(1))


def heave(h5, surface, depth, rake, beta, speed, packing):
    """Soil above the bed's original surface over the wedge's top (from the blade's top edge at
    the surface to where the failure plane comes out), as a height of soil at the bed's packing:
    the surcharge q / gamma of Reece's equation. Mean over the snapshots in the steady window,
    less the same measure at the start (the surface's own roughness)."""
    import h5py
    a, b = math.radians(rake), math.radians(beta)

    def one(g, t):
        x, r = g["position"][()], g["radius"][()]
        tip = speed * t
        lo, hi = tip - depth / math.tan(a), tip + depth / math.tan(b)
        m = (x[:, 0] >= lo) & (x[:, 0] < hi)
        h = np.clip(x[m, 2] + r[m] - surface, 0, 2 * r[m])
        cap = np.pi * h ** 2 * (3 * r[m] - h) / 3
        return float(np.sum(cap)) / ((hi - lo) * BIN_W * packing)

    with h5py.File(h5, "r") as f:
        snaps = [(float(f["particles"][k].attrs["time"]), f["particles"][k]) for k in sorted(f["particles"])]
        start = one(snaps[0][1], 0.0)
        steady = [one(g, t) for t, g in snaps if speed * t >= STEADY_FROM - 1e-9]
    return float(np.mean(steady)) - start


def first_peak(travel, draft):
    """Largest 5 mm running mean of the draft before the steady window."""
    n = max(1, int(np.searchsorted(travel, travel[0] + 0.005)))
    rm = np.convolve(draft, np.ones(n) / n, mode="valid")
    return float(np.max(rm[travel[n - 1:] < STEADY_FROM]))


def blade_forces(h5, rake, speed):
    import h5py
    with h5py.File(h5, "r") as f:
        s = f["/tools/blade/samples"][()]
        if int(f.attrs.get("complete", 0)) != 1:
            raise SystemExit(f"blade_validation: {h5} is incomplete")
    t, fx, fz = s[:, 0], s[:, 1], s[:, 3]
    travel = t * speed
    draft, lift = -fx, fz
    a = math.radians(rake)
    # Normal into the soil n = (sin a, cos a), up the blade b = (-cos a, sin a): the soil pushes
    # the blade along -n and drags it along b while it rides up.
    N = -(fx * math.sin(a) + fz * math.cos(a))
    T = -fx * math.cos(a) + fz * math.sin(a)
    return travel, draft, lift, N, T


def load_material(path):
    """GRAIN, LAW and the deposition friction from a material file (docs/soil.md)."""
    global MATERIAL, GRAIN, LAW, DEPOSITION_FRICTION
    import yaml
    try:
        m = yaml.safe_load(open(path))
    except (OSError, yaml.YAMLError) as e:
        sys.exit(f"blade_validation: --material {path}: cannot read it ({e})")
    try:
        r = m["radius"]
        if isinstance(r, dict):
            if r.get("distribution", "uniform") != "uniform":
                sys.exit(f"blade_validation: --material {path}: radius.distribution must be uniform")
            rmin, rmax = float(r["min"]), float(r["max"])
        else:
            rmin = rmax = float(r)
        GRAIN = dict(density=float(m["density"]), r_min=rmin, r_max=rmax)
        LAW = dict(m["contact"]["particle_particle"])
        DEPOSITION_FRICTION = float((m.get("prepare") or {}).get("deposition_friction", 0.0))
    except (KeyError, TypeError, ValueError) as e:
        sys.exit(f"blade_validation: --material {path}: needs density, radius and "
                 f"contact.particle_particle ({e!r})")
    MATERIAL = os.path.abspath(path)


def safe_dt(build, out):
    """The engine's largest safe dt for the law and model: dem_run refuses dt = 1 s and names it."""
    probe = os.path.join(out, f"dt_probe_{MODEL}.yaml")
    r = 0.5 * (GRAIN["r_min"] + GRAIN["r_max"])
    with open(probe, "w") as f:
        f.write(head_yaml() + walls_yaml().replace("floor, type", "floor, contact: "
                                                   f"{{friction: {BLADE_FRICTION}}}, type") +
                "particles:\n" + model_yaml() +
                f"  list:\n    - {{species: grain, position: [{BIN_L / 2}, {BIN_W / 2}, {3 * r}], "
                f"velocity: [0, 0, 0], radius: {GRAIN['r_min']}}}\n"
                "run: {duration: 0}\noutput: {file: dt_probe.h5}\n")
    txt = subprocess.run([os.path.join(build, "bin", "dem_run"), probe, "--set", "scene.dt=1"],
                         capture_output=True, text=True, cwd=out)
    m = re.search(r"Use scene.dt <= ([0-9.eE+-]+) s", txt.stdout + txt.stderr)
    if not m:
        sys.exit("blade_validation: could not read the largest safe dt from dem_run:\n" + txt.stdout + txt.stderr)
    return float(m.group(1))


def main():
    global ARGS, DEPTHS, RAKES, BIN_L, BIN_W, BED_H, TRAVEL, STEADY_FROM, REACH, DT, SCALE
    global MODEL, BLADE_FRICTION, CONFINING
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default="results/blade")
    p.add_argument("--build", default="build")
    p.add_argument("--seeds", type=int, default=2, help="beds (insertion seeds) per case")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--speed", type=float, default=None,
                   help="blade speed, m/s (default 0.02 x sqrt(D / 1 cm): the default scene's inertial number)")
    p.add_argument("--rate-check", action="store_true",
                   help="also run the deep vertical case of seed 1 at half the speed")
    p.add_argument("--skim", type=float, default=1.0,
                   help="grains whose centre rises this many mean diameters above the surface are removed")
    p.add_argument("--fresh", action="store_true", help="rerun every step")
    p.add_argument("--depths", default=None, help="m or mean diameters (4D), comma-separated (default 4D,6D)")
    p.add_argument("--rakes", default=",".join(str(a) for a in RAKES), help="deg, comma-separated")
    p.add_argument("--bin-length", default=None, help="m or mean diameters (default 28D)")
    p.add_argument("--bin-width", default=None, help="m or mean diameters (default 4D)")
    p.add_argument("--bed-height", default=None, help="m or mean diameters (default 9D)")
    p.add_argument("--material", default=None, help="a material file (configs/materials/*.yaml)")
    p.add_argument("--model", default="translating", choices=["translating", "rotating"],
                   help="particles.model of the cases and the triaxial test")
    p.add_argument("--rolling-friction", type=float, default=ROLLING["friction"],
                   help="rotating model: EPSD rolling friction mu_r, in (0, 1]")
    p.add_argument("--rolling-damping", type=float, default=ROLLING["damping"],
                   help="rotating model: EPSD rolling damping, [0, 1]")
    p.add_argument("--blade-friction", type=float, default=BLADE_FRICTION,
                   help="soil-blade Coulomb friction (delta = atan of it)")
    p.add_argument("--phi", type=float, default=None,
                   help="friction angle for the theory (deg) instead of the triaxial test's (say where it came from)")
    p.add_argument("--lab", default=None, help="the dem_lab to run the triaxial test with (default BUILD/bin/dem_lab)")
    p.add_argument("--test", default="triaxial", choices=["triaxial", "biaxial"],
                   help="the lab test whose angle the theory takes: triaxial (default) or biaxial, "
                        "the plane-strain angle (Reece's wedge is a plane analysis)")
    p.add_argument("--lab-seeds", type=int, default=1,
                   help="samples (seeds) of the lab test; the theory takes the mean of their fits")
    ARGS = p.parse_args()
    if not 1 <= ARGS.lab_seeds <= 10:
        sys.exit("blade_validation: --lab-seeds must lie in 1 .. 10")
    if ARGS.phi is not None and not (10 < ARGS.phi < 70):
        sys.exit("blade_validation: --phi must lie in (10, 70) deg")
    if ARGS.material:
        load_material(ARGS.material)
    dm = GRAIN["r_min"] + GRAIN["r_max"]
    SCALE = dm / D_REF

    def length(txt, what):
        try:
            return float(txt[:-1]) * dm if txt.strip().upper().endswith("D") else float(txt)
        except ValueError:
            sys.exit(f"blade_validation: {what} {txt!r}: give metres or mean diameters (e.g. 4D)")

    DEPTHS = [length(x, "--depths") for x in ARGS.depths.split(",")] if ARGS.depths else \
        [d * SCALE for d in DEPTHS]
    RAKES = [float(x) for x in ARGS.rakes.split(",")]
    BIN_L = length(ARGS.bin_length, "--bin-length") if ARGS.bin_length else BIN_L * SCALE
    BIN_W = length(ARGS.bin_width, "--bin-width") if ARGS.bin_width else BIN_W * SCALE
    BED_H = length(ARGS.bed_height, "--bed-height") if ARGS.bed_height else BED_H * SCALE
    TRAVEL, STEADY_FROM, REACH = TRAVEL * SCALE, STEADY_FROM * SCALE, REACH * SCALE
    if ARGS.speed is None:
        ARGS.speed = 0.02 * math.sqrt(SCALE)
    if not ARGS.speed > 0:
        sys.exit("blade_validation: --speed must be > 0 m/s")
    MODEL = ARGS.model
    if not (0 < ARGS.rolling_friction <= 1) or not (0 <= ARGS.rolling_damping <= 1):
        sys.exit("blade_validation: --rolling-friction must lie in (0, 1], --rolling-damping in [0, 1]")
    ROLLING.update(friction=ARGS.rolling_friction, damping=ARGS.rolling_damping)
    if not ARGS.blade_friction >= 0:
        sys.exit("blade_validation: --blade-friction must be >= 0")
    BLADE_FRICTION = ARGS.blade_friction
    if ARGS.material:
        CONFINING = [p * SCALE for p in [0.5e3, 1.0e3, 2.0e3, 4.0e3]]
    if BIN_W <= 0 or BIN_L <= 0:
        sys.exit("blade_validation: --bin-length and --bin-width must be > 0")
    if max(DEPTHS) > BED_H - 2 * dm or min(DEPTHS) <= 0:
        sys.exit(f"blade_validation: --depths must lie in (0, bed height - 2 D = {BED_H - 2 * dm:g}] m")
    if any(not (0 < a <= 90) for a in RAKES):
        sys.exit("blade_validation: --rakes must lie in (0, 90] deg")
    out = os.path.abspath(ARGS.out)
    build = os.path.abspath(ARGS.build)
    os.makedirs(os.path.join(out, "meshes"), exist_ok=True)
    dem_run = os.path.join(build, "bin", "dem_run")
    global BED_DT
    if MATERIAL or MODEL != "translating":
        DT = float(f"{0.85 * safe_dt(build, out):.3g}")
    BED_DT = DT
    if MODEL != "translating":
        MODEL = "translating"
        BED_DT = float(f"{0.85 * safe_dt(build, out):.3g}") if MATERIAL else 3.0e-5
        MODEL = ARGS.model
    print(f"soil: {'material ' + MATERIAL if MATERIAL else 'the study own grains'}; model {MODEL}"
          + (f" (rolling friction {ROLLING['friction']}, damping {ROLLING['damping']})" if MODEL != "translating" else "")
          + f"; D {dm:g} m; bin {BIN_L:.4g} x {BIN_W:.4g} m, bed {BED_H:.4g} m; depths "
          + ", ".join(f"{d:.4g} m ({d / dm:.3g} D)" for d in DEPTHS)
          + f"; speed {ARGS.speed:.4g} m/s; dt {DT:g} s", flush=True)

    seeds = list(range(1, ARGS.seeds + 1))

    def prep(seed):
        h5 = os.path.join(out, f"bed_s{seed}.h5")
        n, txt = bed_config(seed, out)
        cfg = os.path.join(out, f"bed_s{seed}.yaml")
        if ARGS.fresh or not os.path.exists(h5) or not same_config(cfg, txt):
            with open(cfg, "w") as f:
                f.write(txt)
            print(f"bed seed {seed}: {n} grains", flush=True)
            run([dem_run, cfg], os.path.join(out, f"bed_s{seed}.log"), cwd=out)
        return bed_measures(h5)

    # The triaxial test and the beds side by side.
    with ThreadPoolExecutor(ARGS.jobs) as ex:
        tri = ex.submit(triaxial, out, build)
        beds = dict(zip(seeds, ex.map(prep, seeds)))
        phi, per = tri.result()
    print(f"{ARGS.test} (dem_lab, {len(per)} tests): peak phi through the origin {phi:.2f} deg; per test " +
          ", ".join(f"{s3 / 1e3:g} kPa {ph:.1f} deg at {100 * e:.1f} %" for s3, ph, e, _ in per), flush=True)
    for s, b in beds.items():
        print(f"bed seed {s}: {b['grains']} grains, packing {b['packing']:.3f} inside (1 diameter from "
              f"the walls), {b['slab_packing']:.3f} over the bin's width; bulk density {b['density']:.0f} "
              f"kg/m^3 over the width, coordination {b['coordination']:.2f}, surface at "
              f"{b['surface'] * 100:.2f} cm (+- {b['surface_sd'] * 100:.2f})", flush=True)

    cases = []
    for s in seeds:
        for d in DEPTHS:
            for a in RAKES:
                cases.append((s, d, a, ARGS.speed))
    if ARGS.rate_check:
        cases.append((1, DEPTHS[-1], RAKES[0], ARGS.speed / 2))

    def go(c):
        s, d, a, v = c
        name, cfg, txt = case_config(out, s, d, a, beds[s]["surface"], v, ARGS.skim)
        h5 = os.path.join(out, name + ".h5")
        if ARGS.fresh or not os.path.exists(h5) or not same_config(cfg, txt):
            with open(cfg, "w") as f:
                f.write(txt)
            print(f"run {name}", flush=True)
            run([dem_run, cfg], os.path.join(out, name + ".log"), cwd=out)
        return name, h5

    with ThreadPoolExecutor(ARGS.jobs) as ex:
        files = list(ex.map(go, cases))

    delta = math.degrees(math.atan(BLADE_FRICTION))
    rho_b = float(np.mean([b["density"] for b in beds.values()]))
    gamma = rho_b * G
    d50 = GRAIN["r_min"] + GRAIN["r_max"]
    rows, curves = [], {}
    for (s, d, a, v), (name, h5) in zip(cases, files):
        travel, draft, lift, N, T = blade_forces(h5, a, v)
        w = (travel >= STEADY_FROM) & (travel <= TRAVEL)
        theory, ng, beta = wedge(build, phi, delta, a, gamma, d, BIN_W)
        # The heave: soil above the original surface over the wedge (a diagnostic; as a
        # surcharge q = gamma h_q it would add F 2 h_q / d, since for this wedge N_q = 2 N_gamma,
        # but it is the wedge's own dilated soil, not extra weight: docs/soil_blade.md).
        hq = heave(h5, beds[s]["surface"], d, a, beta, v, beds[s]["slab_packing"])
        # Inertial number of the wedge: shear rate v / d, mean stress at mid-depth of the wedge
        # gamma (d / 2) (1 + K) / 2 with K the passive ratio of the wedge's normal force.
        p_mid = gamma * d / 2 * (1 + 2 * ng) / 2
        inertial = v / d * d50 * math.sqrt(GRAIN["density"] / p_mid)
        # The triaxial angle at the wedge's own stress: the per-test peaks interpolated linearly
        # in log(sigma_3) at p_mid (held at the end values outside the tested range).
        ps = np.log([q[0] for q in per])
        phi_p = float(np.interp(math.log(p_mid), ps, [q[1] for q in per]))
        theory_p = wedge(build, phi_p, delta, a, gamma, d, BIN_W)[0]
        # Standard error of the window mean from 4 blocks of the window (the force swings with
        # each new shear band, about once per 1-2 cm of travel; samples are not independent).
        blocks = [float(np.mean(b)) for b in np.array_split(draft[w], 4)]
        # The interface friction the blade mobilised (tangential over normal force in the window;
        # above atan(mu_blade) where grains push on the tip edge), capped at phi.
        delta_mob = math.degrees(math.atan(np.mean(T[w]) / np.mean(N[w])))
        theory_pd = wedge(build, phi_p, min(max(delta_mob, 0.0), phi_p), a, gamma, d, BIN_W)[0]
        rows.append(dict(seed=s, depth=d, rake=a, speed=v, mean=float(np.mean(draft[w])),
                         std=float(np.std(draft[w])), se=float(np.std(blocks, ddof=1) / 2), peak=first_peak(travel, draft),
                         lift=float(np.mean(lift[w])),
                         delta_mob=delta_mob, theory_pd=theory_pd, phi_p=phi_p, theory_p=theory_p,
                         theory=theory, n_gamma=ng, inertial=inertial, hq=hq))
        curves[(s, d, a, v)] = (travel, draft)

    # Per case: mean over seeds of the window means; the scatter is the larger of the seeds'
    # spread and the window std of a seed divided by sqrt(windows) (reported both).
    print()
    print(f"phi {phi:.2f} deg ({ARGS.test} peak), delta {delta:.2f} deg (atan {BLADE_FRICTION}), "
          f"gamma {gamma:.0f} N/m^3 (bulk density {rho_b:.0f}), width {BIN_W} m, speed {ARGS.speed} m/s, "
          f"steady window {STEADY_FROM}-{TRAVEL} m of travel")
    hdr = ("depth m | rake deg | speed m/s | DEM draft N per seed (window sd, +- block se) | mean +- sd of seeds | "
           "theory N | DEM/theory | phi(p) deg | theory at phi(p) N | DEM/that | delta_mob deg | "
           "theory at phi(p), delta_mob N | DEM/that | heave h_q mm | first peak N | I")
    print(hdr)
    summary = []
    keys = sorted({(r["depth"], r["rake"], r["speed"]) for r in rows}, key=lambda k: (-k[1], k[0], -k[2]))
    for k in keys:
        rs = [r for r in rows if (r["depth"], r["rake"], r["speed"]) == k]
        m = float(np.mean([r["mean"] for r in rs]))
        sd_seeds = float(np.std([r["mean"] for r in rs], ddof=1)) if len(rs) > 1 else float("nan")
        th = rs[0]["theory"]
        summary.append(dict(depth=k[0], rake=k[1], speed=k[2], seeds=len(rs), dem=m, sd_seeds=sd_seeds,
                            window_sd=float(np.mean([r["std"] for r in rs])),
                            block_se=float(np.sqrt(np.sum([r["se"] ** 2 for r in rs])) / len(rs)), theory=th, ratio=m / th,
                            peak=float(np.mean([r["peak"] for r in rs])),
                            lift=float(np.mean([r["lift"] for r in rs])),
                            delta_mob=float(np.mean([r["delta_mob"] for r in rs])),
                            inertial=rs[0]["inertial"], n_gamma=rs[0]["n_gamma"],
                            hq=float(np.mean([r["hq"] for r in rs])), phi_p=rs[0]["phi_p"],
                            theory_p=rs[0]["theory_p"]))
        summary[-1]["ratio_p"] = m / summary[-1]["theory_p"]
        summary[-1]["theory_pd"] = float(np.mean([r["theory_pd"] for r in rs]))
        summary[-1]["ratio_pd"] = m / summary[-1]["theory_pd"]
        per_seed = ", ".join(f"{r['mean']:.2f} ({r['std']:.2f}, +- {r['se']:.2f})" for r in rs)
        print(f"{k[0]:.3f} | {k[1]:.0f} | {k[2]:g} | {per_seed} | {m:.2f} +- {sd_seeds:.2f} | {th:.2f} | "
              f"{m / th:.3f} | {summary[-1]['phi_p']:.1f} | {summary[-1]['theory_p']:.2f} | {summary[-1]['ratio_p']:.3f} | "
              f"{summary[-1]['delta_mob']:.1f} | {summary[-1]['theory_pd']:.2f} | {summary[-1]['ratio_pd']:.3f} | "
              f"{1000 * summary[-1]['hq']:.1f} | {summary[-1]['peak']:.2f} | {rs[0]['inertial']:.1e}")
    with open(os.path.join(out, f"blade_summary{tag()}{lab_tag()}.csv"), "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(summary[0].keys()))
        wr.writeheader()
        wr.writerows(summary)

    print()
    main_speed = [r for r in summary if r["speed"] == ARGS.speed]
    d1, d2 = DEPTHS[0], DEPTHS[-1]
    for a in (RAKES if len(DEPTHS) > 1 else []):
        f1 = [r for r in main_speed if r["rake"] == a and r["depth"] == d1][0]
        f2 = [r for r in main_speed if r["rake"] == a and r["depth"] == d2][0]
        print(f"depth trend, rake {a:.0f}: F({d2})/F({d1}) DEM {f2['dem'] / f1['dem']:.3f}, theory "
              f"(d2/d1)^2 {(d2 / d1) ** 2:.3f}, ratio {f2['dem'] / f1['dem'] / (d2 / d1) ** 2:.3f}; theory at phi(p) "
              f"{f2['theory_p'] / f1['theory_p']:.3f}")
    for d in (DEPTHS if len(RAKES) > 1 else []):
        fa = [r for r in main_speed if r["rake"] == RAKES[0] and r["depth"] == d][0]
        fb = [r for r in main_speed if r["rake"] == RAKES[1] and r["depth"] == d][0]
        print(f"rake trend, depth {d}: F({RAKES[1]:.0f})/F({RAKES[0]:.0f}) DEM {fb['dem'] / fa['dem']:.3f}, "
              f"theory {fb['theory'] / fa['theory']:.3f}, at phi(p) {fb['theory_p'] / fa['theory_p']:.3f}")
    rc = [r for r in summary if r["speed"] != ARGS.speed]
    if rc:
        base = [r for r in main_speed if r["rake"] == rc[0]["rake"] and r["depth"] == rc[0]["depth"]][0]
        seed1 = [r for r in rows if r["seed"] == 1 and r["depth"] == rc[0]["depth"] and r["rake"] == rc[0]["rake"]]
        print(f"rate check (seed 1, depth {rc[0]['depth']}, rake {rc[0]['rake']:.0f}): speed {rc[0]['speed']:g} m/s "
              f"{rc[0]['dem']:.2f} N against {[r['mean'] for r in seed1 if r['speed'] == ARGS.speed][0]:.2f} N at "
              f"{ARGS.speed:g} m/s")

    plot(out, summary, curves, phi, delta)


def plot(out, summary, curves, phi, delta):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.8))
    colours = {}
    for (s, d, a, v), (travel, draft) in sorted(curves.items()):
        if v != ARGS.speed:
            continue
        key = (d, a)
        c = colours.setdefault(key, f"C{len(colours)}")
        # 5 mm running mean for the chart
        n = max(1, int(len(travel) * 0.005 / TRAVEL))
        k = np.ones(n) / n
        ax[0].plot(travel[n - 1:] * 100, np.convolve(draft, k, mode="valid"), color=c, lw=0.8,
                   label=f"d {d * 100:g} cm, rake {a:.0f} deg" if s == 1 else None)
    for r in summary:
        if r["speed"] != ARGS.speed:
            continue
        c = colours[(r["depth"], r["rake"])]
        ax[0].axhline(r["theory"], color=c, ls="--", lw=1)
    ax[0].axvspan(STEADY_FROM * 100, TRAVEL * 100, color="0.9", zorder=0)
    ax[0].set_xlabel("blade travel (cm)")
    ax[0].set_ylabel("draft force (N)")
    ax[0].set_title("DEM draft (5 mm running mean; grey: steady window) and Reece (dashed)", fontsize=9)
    ax[0].legend(fontsize=8)
    for a, mk in zip(RAKES, ["o", "s"]):
        rs = [r for r in summary if r["rake"] == a and r["speed"] == ARGS.speed]
        d = np.array([r["depth"] for r in rs])
        col = "C3" if a == RAKES[0] else "C0"
        ax[1].errorbar(d * 100, [r["dem"] for r in rs],
                       yerr=[r["sd_seeds"] if r["sd_seeds"] == r["sd_seeds"] else r["block_se"] for r in rs],
                       fmt=mk, color=col, capsize=3, label=f"DEM rake {a:.0f} deg")
        dd = np.linspace(0, max(DEPTHS) * 1.1, 50)
        th = rs[0]["theory"] * (dd / rs[0]["depth"]) ** 2
        ax[1].plot(dd * 100, th, "--", color=col, label=f"Reece rake {a:.0f} deg, phi {phi:.1f} deg")
        ax[1].plot(d * 100, [r["theory_p"] for r in rs], "x", color=col, ms=8,
                   label=f"Reece rake {a:.0f} deg, {ARGS.test} phi at the wedge's stress")
    ax[1].set_xlabel("depth (cm)")
    ax[1].set_ylabel("steady draft force (N)")
    ax[1].set_title(f"phi {phi:.1f} deg ({ARGS.test}), delta {delta:.1f} deg, width {BIN_W * 100:g} cm", fontsize=9)
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    png = os.path.join(out, f"blade_validation{tag()}{lab_tag()}.png")
    fig.savefig(png, dpi=120)
    print("chart:", png)


if __name__ == "__main__":
    main()
