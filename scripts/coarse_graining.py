#!/usr/bin/python3
"""Coarse graining of dry sand: the same material at grains s times the radius, checked against
the bulk targets and charted against the fine grains (docs/soil_models.md "Coarse graining").

    /usr/bin/python3 scripts/coarse_graining.py lab [--sizes 1,1.5,2,3] [--seeds 3] [--jobs 1]
    /usr/bin/python3 scripts/coarse_graining.py blade [--sizes 3,2,1.5,1] [--seeds 4]
    /usr/bin/python3 scripts/coarse_graining.py chart [--study results/coarse_graining/wheel_loader]

lab:   the calibration's confirmation protocol of scripts/calibrate.py (its own runner, imported:
       the deposition bed of 1,100 grains, the 300-grain triaxial at 10 kPa, the 500-grain heap,
       fresh seeds 101, 102, ...) at the calibrated law of configs/materials/dry_sand.yaml
       (mu, deposition friction, k_N in Pa) with the grain radius x s; each target's mean +- 95 %
       t-interval, and a verdict: "met" within the tolerance, "missed" when the mean misses by
       more than the tolerance and the target lies outside the interval (a miss beyond the
       interval: recalibrate with scripts/calibrate.py), else "within its interval". Writes
       results/coarse_graining/lab.json (and caches the runs in results/coarse_graining/lab/).
       Also reads the prepared piles (results/pile_dry_sand[_cg<T>]_bed.h5: packing, bulk
       density and coordination of stage 1) and measures the slope of each released pile's
       face (results/pile_dry_sand[_cg<T>].h5).
blade: a vertical blade pushed through the same bin of dry sand (in metres: 3.78 x 1.08 m,
       bed about 1.2 m, cut 0.81 m deep, 0.2 m/s, 1.08 m of travel) at each grain size, one
       bed per seed (inserted with particles.coarse_grain, deposited and frozen); the draft per
       metre over the second half of the travel, mean +- 95 % over the beds. Writes
       results/coarse_graining/blade.json (runs in results/coarse_graining/blade/).
chart: the wheel-loader ensembles of configs/studies/coarse_graining_wheel_loader.yaml (run
       with master/studies/study.py first) and, when there, lab.json and
       results/coarse_graining/blade.json: payload at 7 s and the mean A-bearing longitudinal
       force over 2-7 s (members, mean, 95 % t-interval) against grain size and against the CPU
       seconds of a member, the reference's interval as a band; names the coarsest grain whose
       outcomes are within the scatter of the finest (Welch 95 % interval of the difference
       contains 0 for both outcomes and the permutation test on the force series is not
       significant). Writes results/coarse_graining/coarse_graining.png and summary.json and
       prints the table.
"""
import argparse
import json
import math
import os
import statistics
import sys

import numpy as np
import yaml

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "scripts"))
import calibrate  # noqa: E402  (its runner and statistics: the same protocol as the calibration)

OUT = os.path.join(REPO, "results", "coarse_graining")
MATERIAL = os.path.join(REPO, "configs", "materials", "dry_sand.yaml")
TARGETS = os.path.join(REPO, "configs", "materials", "dry_sand.targets.yaml")


def tag(s):
    return "" if s == 1 else "_cg" + f"{s:g}".replace(".", "p")


def sizes_arg(text):
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"coarse_graining: --sizes '{text}': give grain size factors separated "
                         f"by commas, e.g. 1,1.5,2,3")
    if not vals or any(not (1.0 <= v <= 5.0) for v in vals):
        raise SystemExit(f"coarse_graining: --sizes '{text}': each factor must be in [1, 5]")
    return vals


# --- lab -----------------------------------------------------------------------------------------

def pile_stats(s):
    """Stage 1's measured packing (the /bed attributes) and the released pile's face slope."""
    import h5py
    out = {}
    bed = os.path.join(REPO, "results", f"pile_dry_sand{tag(s)}_bed.h5")
    if os.path.exists(bed):
        with h5py.File(bed, "r") as f:
            a = f["bed"].attrs
            out.update({k: float(a[k]) for k in ("packing_fraction", "bulk_density",
                                                  "coordination", "grains_measured",
                                                  "max_overlap_ratio")})
            out["grains"] = int(f["x"].shape[0])
    pile = os.path.join(REPO, "results", f"pile_dry_sand{tag(s)}.h5")
    if os.path.exists(pile):
        with h5py.File(pile, "r") as f:
            x, r = np.asarray(f["x"]), np.asarray(f["radius"])
        out["face_slope_deg"] = face_slope(x, r)
    return out


def face_slope(x, r):
    """The slope of the pile's free face: the top surface z_top(x) = max(z + r) in bins one mean
    diameter wide along x, fitted by a line over the face (where the surface lies between 15 %
    and 85 % of the bed's top height, from the toe up to the crest)."""
    d = 2 * float(np.mean(r))
    top = x[:, 2] + r
    edges = np.arange(x[:, 0].min() - r.max(), x[:, 0].max() + r.max() + d, d)
    centres, heights = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        m = (x[:, 0] >= a) & (x[:, 0] < b)
        if m.any():
            centres.append(0.5 * (a + b))
            heights.append(float(top[m].max()))
    centres, heights = np.array(centres), np.array(heights)
    hmax = float(np.percentile(heights, 90))
    # the face: from the toe to the first bin that reaches 85 % of the top height
    crest = int(np.argmax(heights >= 0.85 * hmax))
    sel = np.arange(len(heights)) <= crest
    sel &= heights >= 0.15 * hmax
    if sel.sum() < 2:
        return float("nan")
    k = np.polyfit(centres[sel], heights[sel], 1)[0]
    return float(math.degrees(math.atan(abs(k))))


def lab(args):
    with open(MATERIAL) as f:
        mat = yaml.safe_load(f)
    pp = mat["contact"]["particle_particle"]
    mu, dep = float(pp["friction"]), float(mat["prepare"]["deposition_friction"])
    base = calibrate.read_targets(TARGETS)
    targets = base["targets"]
    seeds = list(range(101, 101 + args.seeds))
    os.makedirs(OUT, exist_ok=True)
    result = {"material": os.path.relpath(MATERIAL, REPO), "friction": mu,
              "deposition_friction": dep, "normal_stiffness_Pa": float(pp["normal_stiffness"]),
              "seeds": seeds, "targets": targets, "sizes": {}}
    print(f"coarse_graining lab: mu {mu}, deposition friction {dep}, k_N {pp['normal_stiffness']:.4g} "
          f"Pa, seeds {seeds}")
    for s in args.sizes:
        cfg = json.loads(json.dumps(base))  # a copy
        cfg["grains"]["radius"] = (base["grains"]["radius"][0] * s, base["grains"]["radius"][1] * s)
        cfg["grains"]["kN"] = float(pp["normal_stiffness"])  # the material's (Pa), not re-derived
        d = cfg["design"]
        run = calibrate.Runner(cfg, os.path.join(OUT, "lab", f"s{s:g}"),
                               os.path.join(REPO, "build", "bin"), args.jobs)
        calls = [(run.deposition, (mu, dep, sd, d["deposition_grains"])) for sd in seeds]
        calls += [(run.triaxial, (mu, dep, sd, d["triaxial_grains"])) for sd in seeds]
        calls += [(run.repose, (mu, sd, d["repose_grains"])) for sd in seeds]
        vals = {}
        for res in run.many(calls):
            for k, v in res.items():
                vals.setdefault(k, []).append(v)
        row = {"radius": list(cfg["grains"]["radius"])}
        for k, v in vals.items():
            st = calibrate.stats(v)
            entry = {"mean": round(st["mean"], 4), "sd": round(st["sd"], 4),
                     "ci95": round(st["ci95"], 4), "values": st["values"]}
            if k in targets:
                t = targets[k]
                miss = st["mean"] - t["value"]
                inside = abs(miss) <= st["ci95"]
                entry["verdict"] = ("met" if abs(miss) <= t["tolerance"] else
                                    "within its interval" if inside else "missed")
            row[k] = entry
        row["pile"] = pile_stats(s)
        result["sizes"][f"{s:g}"] = row
        print(f"  {s:g}x (r {row['radius'][0]:.4g}-{row['radius'][1]:.4g} m): " + "; ".join(
            f"{k} {e['mean']:.4g} +- {e['ci95']:.3g}" + (f" ({e['verdict']})" if "verdict" in e else "")
            for k, e in row.items() if isinstance(e, dict) and "mean" in e), flush=True)
        p = row["pile"]
        if p:
            print(f"     pile: {p.get('grains', 0)} grains, stage 1 packing {p.get('packing_fraction', float('nan')):.4f}, "
                  f"bulk density {p.get('bulk_density', float('nan')):.0f} kg/m^3, coordination "
                  f"{p.get('coordination', float('nan')):.2f} ({p.get('grains_measured', 0):.0f} grains inside); "
                  f"released face {p.get('face_slope_deg', float('nan')):.1f} deg")
    path = os.path.join(OUT, "lab.json")
    with open(path, "w") as f:
        json.dump(result, f, indent=1)
    print(f"coarse_graining lab: wrote {os.path.relpath(path, REPO)}")
    missed = [(s, k) for s, row in result["sizes"].items() for k, e in row.items()
              if isinstance(e, dict) and e.get("verdict") == "missed"]
    if missed:
        print("coarse_graining lab: missed beyond the interval (recalibrate): " +
              ", ".join(f"{s}x {k}" for s, k in missed))
    return 0


# --- chart ---------------------------------------------------------------------------------------

STUDY_SIZES = {"cg1": 1.0, "cg1p5": 1.5, "cg2": 2.0, "cg3": 3.0}
PAYLOAD = "payload at 7 s [t]"
FORCE = "A long. mean 2-7 s [kN]"


def welch(a, b):
    """Difference of means b - a with its Welch 95 % interval."""
    ma, mb = statistics.mean(a), statistics.mean(b)
    va, vb = statistics.variance(a) / len(a), statistics.variance(b) / len(b)
    se = math.sqrt(va + vb)
    if se == 0:
        return mb - ma, 0.0
    dof = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1))
    return mb - ma, calibrate.t95(int(math.floor(dof))) * se


def member_outcomes(study_dir, variant):
    """Per member: outcomes and CPU seconds (the study's m<i>.json and its summary.json)."""
    rows = []
    vdir = os.path.join(study_dir, variant)
    i = 0
    while os.path.exists(os.path.join(vdir, f"m{i}.json")):
        with open(os.path.join(vdir, f"m{i}.json")) as f:
            m = json.load(f)
        if m.get("exit_code") == 0:
            rows.append(m)
        i += 1
    return rows


def chart(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    study_dir = os.path.join(REPO, args.study)
    with open(os.path.join(study_dir, "summary.json")) as f:
        summary = json.load(f)
    outcomes, cpu, verdict = {}, {}, {}
    for v in summary["variants"]:
        name = v["name"]
        if name not in STUDY_SIZES:
            continue
        outs = v.get("outcomes", {})
        outcomes[name] = {k: [x for x in outs[k] if math.isfinite(x)] for k in (PAYLOAD, FORCE)
                          if k in outs}
        cpu[name] = [m["cpu_seconds"] for m in member_outcomes(study_dir, name)]
        c = v.get("comparison", {})
        verdict[name] = c.get("verdict"), c.get("p_value"), c.get("distance")
    if "cg1" not in outcomes or not outcomes["cg1"]:
        raise SystemExit("coarse_graining chart: the reference (cg1) has no members yet: run "
                         "master/studies/study.py configs/studies/coarse_graining_wheel_loader.yaml")
    lab_path = os.path.join(OUT, "lab.json")
    labd = json.load(open(lab_path)) if os.path.exists(lab_path) else None
    blade_path = os.path.join(OUT, "blade.json")
    blade = json.load(open(blade_path)) if os.path.exists(blade_path) else None

    table, coarsest = [], 1.0
    ref = outcomes["cg1"]
    for name, s in sorted(STUDY_SIZES.items(), key=lambda kv: kv[1]):
        if name not in outcomes or not outcomes[name].get(PAYLOAD):
            continue
        row = {"size": s, "members": len(outcomes[name][PAYLOAD]),
               "cpu_s": statistics.mean(cpu[name]) if cpu[name] else float("nan"),
               "verdict": verdict[name][0], "p_value": verdict[name][1],
               "distance": verdict[name][2]}
        within = True
        for k in (PAYLOAD, FORCE):
            vals = outcomes[name][k]
            st = calibrate.stats(vals)
            row[k] = {"mean": st["mean"], "ci95": st["ci95"], "sd": st["sd"], "values": vals}
            if name != "cg1":
                diff, half = welch(ref[k], vals)
                row[k]["diff"], row[k]["diff_ci95"] = diff, half
                if abs(diff) > half:
                    within = False
        if name != "cg1" and verdict[name][0] == "significant":
            within = False
        row["within_scatter_of_1x"] = within if name != "cg1" else None
        if name != "cg1" and within and s > coarsest:
            # the coarsest grain such that it and every finer one are within scatter
            if all(r.get("within_scatter_of_1x") in (None, True) for r in table):
                coarsest = s
        table.append(row)

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.8))
    colours = {1.0: "k", 1.5: "tab:blue", 2.0: "tab:orange", 3.0: "tab:red"}
    for j, (k, lab_) in enumerate([(PAYLOAD, "payload at 7 s [t]"),
                                   (FORCE, "A-bearing longitudinal, mean 2-7 s [kN]")]):
        a = ax[j]
        r0 = next(r for r in table if r["size"] == 1.0)[k]
        a.axhspan(r0["mean"] - r0["ci95"], r0["mean"] + r0["ci95"], color="0.85",
                  label="1x mean +- 95 %")
        for r in table:
            c = colours.get(r["size"], "tab:green")
            mcpu = [x for x in cpu[[n for n, s in STUDY_SIZES.items() if s == r["size"]][0]]]
            vals = r[k]["values"]
            a.scatter(mcpu[:len(vals)], vals, s=14, color=c, alpha=0.5)
            a.errorbar([r["cpu_s"]], [r[k]["mean"]], yerr=[r[k]["ci95"]], fmt="o", color=c,
                       capsize=4, label=f"{r['size']:g}x grains ({r['members']} members)")
            a.annotate(f"{r['size']:g}x", (r["cpu_s"], r[k]["mean"]), textcoords="offset points",
                       xytext=(8, -4), fontsize=9, color=c)
        a.set_xscale("log")
        a.set_xlabel("CPU seconds per 7 s member (master + machine + soil)")
        a.set_ylabel(lab_)
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    if blade and "1" in blade["sizes"]:
        b0 = blade["sizes"]["1"]["mean"]
        bs = sorted(blade["sizes"], key=float)
        ax[2].errorbar([float(k) for k in bs], [blade["sizes"][k]["mean"] / b0 for k in bs],
                       yerr=[blade["sizes"][k]["ci95"] / b0 for k in bs], fmt="D-.", color="tab:purple",
                       capsize=4, label=f"blade draft / 1x ({len(blade['sizes']['1']['seeds'])} beds per size)")
    a = ax[2]
    xs = [r["size"] for r in table]
    for k, mk, lab_ in [(PAYLOAD, "o", "payload / 1x"), (FORCE, "s", "A-bearing mean / 1x")]:
        r0 = table[0][k]["mean"]
        a.errorbar(xs, [r[k]["mean"] / r0 for r in table], yerr=[r[k]["ci95"] / abs(r0) for r in table],
                   fmt=mk + "-", capsize=4, label=lab_)
    if labd:
        ls = sorted(float(s) for s in labd["sizes"])
        for key, mk, lab_ in [("peak_friction_angle", "^", "lab peak friction angle / target"),
                              ("bulk_density", "v", "lab bulk density / target")]:
            t = labd["targets"][key]["value"]
            a.errorbar(ls, [labd["sizes"][f"{s:g}"][key]["mean"] / t for s in ls],
                       yerr=[labd["sizes"][f"{s:g}"][key]["ci95"] / t for s in ls],
                       fmt=mk + ":", capsize=3, alpha=0.7, label=lab_)
    a.axhline(1.0, color="0.5", lw=0.8)
    a.set_xlabel("grain size factor s (radius / 6-7.5 cm)")
    a.set_ylabel("ratio (mean +- 95 %)")
    a.set_xticks(xs)
    a3 = a.twinx()
    a3.plot(xs, [r["cpu_s"] for r in table], "k--", lw=1, label="CPU s per member (right)")
    a3.set_yscale("log")
    a3.set_ylabel("CPU seconds per member (log)")
    h1, l1 = a.get_legend_handles_labels()
    h2, l2 = a3.get_legend_handles_labels()
    a.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
    a.grid(alpha=0.3)
    verdict_text = (f"the coarsest grain within the scatter of 1x is {coarsest:g}x" if coarsest > 1
                    else "no coarser grain is within the scatter of 1x")
    fig.suptitle(f"Coarse graining, wheel loader in dry sand (7 s, H 1 ms, ensembles; Welch 95 % "
                 f"and permutation test against 1x): {verdict_text}")
    fig.tight_layout()
    png = os.path.join(OUT, "coarse_graining.png")
    fig.savefig(png, dpi=110)

    print("| grains | members | CPU s per member | payload at 7 s [t] | vs 1x | A-bearing long. mean 2-7 s [kN] | vs 1x | series vs 1x (permutation test) |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |")
    for r in table:
        def cell(k):
            e = r[k]
            return f"{e['mean']:.2f} +- {e['ci95']:.2f}" if k == PAYLOAD else f"{e['mean']:.1f} +- {e['ci95']:.1f}"

        def diff(k, fmt):
            e = r[k]
            if "diff" not in e:
                return ""
            star = "*" if abs(e["diff"]) > e["diff_ci95"] else ""
            return f"{e['diff']:+{fmt}} [{e['diff'] - e['diff_ci95']:+{fmt}}, {e['diff'] + e['diff_ci95']:+{fmt}}]{star}"
        ver = "" if r["size"] == 1.0 else f"{r['verdict']} (p {r['p_value']:.3f}, distance {r['distance']:.3f})" \
            if r["p_value"] is not None else str(r["verdict"])
        print(f"| {r['size']:g}x | {r['members']} | {r['cpu_s']:.0f} | {cell(PAYLOAD)} | {diff(PAYLOAD, '.2f')} | "
              f"{cell(FORCE)} | {diff(FORCE, '.1f')} | {ver} |")
    print(f"coarsest grain within the scatter of 1x: {coarsest:g}x" + (" (none coarser)" if coarsest == 1 else ""))
    if blade and "1" in blade["sizes"]:
        print(f"\nblade ({blade['label']}): draft per metre of blade over the steady window, mean +- 95 % over the beds")
        print("| grains | grains in the bin | beds | CPU s per cut | draft [kN/m] | vs 1x [kN/m] |")
        print("| --- | ---: | ---: | ---: | ---: | --- |")
        ref_b = [r["mean_N"] / 1e3 / BLADE["width"] for r in blade["sizes"]["1"]["seeds"]]
        for k in sorted(blade["sizes"], key=float):
            e = blade["sizes"][k]
            vals = [r["mean_N"] / 1e3 / BLADE["width"] for r in e["seeds"]]
            d = ""
            if k != "1":
                dm, h = welch(ref_b, vals)
                e["diff_kN_per_m"], e["diff_ci95"] = dm, h
                d = f"{dm:+.1f} [{dm - h:+.1f}, {dm + h:+.1f}]" + ("*" if abs(dm) > h else "")
            print(f"| {float(k):g}x | {e['grains']} | {len(vals)} | {e['cpu_seconds']:.0f} | "
                  f"{e['mean'] / 1e3:.1f} +- {e['ci95'] / 1e3:.1f} | {d} |")
    with open(os.path.join(OUT, "summary.json"), "w") as f:
        json.dump({"table": table, "coarsest_within_scatter": coarsest, "lab": labd,
                   "blade": blade}, f, indent=1, default=str)
    print(f"coarse_graining chart: wrote {os.path.relpath(png, REPO)}")
    return 0



# --- blade ---------------------------------------------------------------------------------------
# A vertical blade pushed through a bin of dry sand at each grain size: the same scene in metres
# (bin, bed height, cut depth, speed, skim), only the grains coarsened (the bed inserted with
# particles.coarse_grain s; the cut loads it with the radius and the DEM step written out, as a
# checkpoint refuses coarse_grain). The bin is 1.08 m thick with smooth side walls (plane
# strain): 8 mean diameters at 1x, 4 at 2x, 2.7 at 3x.
BLADE = dict(length=3.78, width=1.08, bed=1.215, depth=0.81, travel=1.08, speed=0.2,
             steady_from=0.54, skim=0.405, dt=1.2e-4)


def blade_configs(s, seed, out):
    g = calibrate.read_targets(TARGETS)["grains"]
    r1 = (g["radius"][0], g["radius"][1])
    vmean = 4.0 / 3.0 * math.pi * (r1[1] ** 4 - r1[0] ** 4) / (4 * (r1[1] - r1[0]))
    L, W, H = BLADE["length"], BLADE["width"], BLADE["bed"]
    count = int(round(L * W * H * 0.6 / vmean))  # at 1x; coarse_grain divides it by s^3
    walls = (f"walls:\n  - {{name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}\n"
             f"  - {{name: back, type: plane, point: [0, 0, 0], normal: [1, 0, 0], contact: {{friction: 0.0}}}}\n"
             f"  - {{name: front, type: plane, point: [{L}, 0, 0], normal: [-1, 0, 0], contact: {{friction: 0.0}}}}\n"
             f"  - {{name: side0, type: plane, point: [0, 0, 0], normal: [0, 1, 0], contact: {{friction: 0.0}}}}\n"
             f"  - {{name: side1, type: plane, point: [0, {W}, 0], normal: [0, -1, 0], contact: {{friction: 0.0}}}}\n")
    head = (f"scene:\n  dt: {BLADE['dt']}\n  gravity: [0, 0, -9.81]\n  broad_phase_interval: 5\n"
            f"  skin: 0.5\n  threads: 1\nmaterials:\n  sand: {{file: {MATERIAL}}}\n")
    bed = os.path.join(out, f"bed_s{seed}.h5")
    with open(os.path.join(out, "bed.yaml"), "w") as f:
        f.write(head + "species:\n  - {name: grain, material: sand}\n" + walls +
                f"particles:\n  coarse_grain: {s}\n  insert:\n    - {{species: grain, min: [0, 0, 0], "
                f"max: [{L}, {W}, {3.5 * H:.4f}], count: {count}, seed: {seed}}}\n"
                f"prepare:\n  ke_per_particle: {3e-4 * s ** 3:.6g}\n  max_time: 6.0\n  margin: {1.0 / s:.4g}\n"
                f"  checkpoint: {bed}\nrun:\n  duration: 0\noutput:\n  file: {os.path.join(out, 'bed_run.h5')}\n")
    return bed, count, (r1[0] * s, r1[1] * s)


def surface_height(bed, L):
    import h5py
    with h5py.File(bed, "r") as f:
        x, r = np.asarray(f["x"]), np.asarray(f["radius"])
    d = 2 * float(np.mean(r))
    tops = []
    for a in np.arange(0.15 * L, 0.85 * L, d):  # away from the end walls
        m = (x[:, 0] >= a) & (x[:, 0] < a + d)
        if m.any():
            tops.append(float((x[m, 2] + r[m]).max()))
    return float(np.mean(tops)), len(r)


def blade(args):
    results = {"scene": BLADE, "sizes": {}, "label": f"vertical blade, {BLADE['depth']} m deep, "
               f"{BLADE['speed']} m/s, bin {BLADE['length']} x {BLADE['width']} m"}
    W = BLADE["width"]
    for s in args.sizes:
        per_seed = []
        for seed in range(1, args.seeds + 1):
            per_seed.append(blade_cut(s, seed))
        means = [r["mean_N"] for r in per_seed]
        st = calibrate.stats(means)
        results["sizes"][f"{s:g}"] = {
            "grains": per_seed[0]["grains"], "seeds": per_seed, "mean": st["mean"] / W,
            "ci95": st["ci95"] / W, "sd": st["sd"] / W,
            "cpu_seconds": statistics.mean(r["cpu_seconds"] for r in per_seed)}
        e = results["sizes"][f"{s:g}"]
        print(f"  blade {s:g}x: draft {e['mean'] / 1e3:.2f} +- {e['ci95'] / 1e3:.2f} kN/m (sd "
              f"{e['sd'] / 1e3:.2f}, {len(means)} beds), {e['cpu_seconds']:.0f} CPU s per cut", flush=True)
        with open(os.path.join(OUT, "blade.json"), "w") as f:
            json.dump(results, f, indent=1)
    return 0


def blade_cut(s, seed):
    import h5py
    import subprocess
    L, W = BLADE["length"], BLADE["width"]
    out = os.path.join(OUT, "blade", f"s{s:g}", f"seed{seed}")
    os.makedirs(out, exist_ok=True)
    bed, count, (rmin, rmax) = blade_configs(s, seed, out)
    if not os.path.exists(bed):
        r = subprocess.run(["nice", os.path.join(REPO, "build", "bin", "dem_run"),
                            os.path.join(out, "bed.yaml")], capture_output=True, text=True)
        open(os.path.join(out, "bed.log"), "w").write(r.stdout + r.stderr)
        if r.returncode != 0:
            raise SystemExit(f"coarse_graining blade: the bed at {s:g}x failed: {r.stderr[-800:]}")
    surf, n = surface_height(bed, L)
    bottom = surf - BLADE["depth"]
    T = BLADE["travel"] / BLADE["speed"]
    case = os.path.join(out, "case.yaml")
    mesh = os.path.join(out, "blade.obj")
    with open(mesh, "w") as f:  # a vertical rectangle spanning the bin, 2 m high
        f.write(f"v 0 -0.1 0\nv 0 {W + 0.1} 0\nv 0 {W + 0.1} 2.0\nv 0 -0.1 2.0\nf 1 2 3\nf 1 3 4\n")
    dt = BLADE["dt"] * s
    with open(case, "w") as f:
        f.write(f"scene:\n  dt: {dt:.6g}\n  gravity: [0, 0, -9.81]\n  broad_phase_interval: 5\n"
                f"  skin: 0.5\n  threads: 1\n  region: {{min: [-1, -1, -1], max: [{L + 1}, {W + 1}, {surf + BLADE['skim']:.4f}]}}\n"
                f"materials:\n  sand: {{file: {MATERIAL}}}\n"
                f"species:\n  - {{name: grain, material: sand, radius: {{distribution: uniform, min: {rmin:.6g}, max: {rmax:.6g}}}}}\n")
        f.write("walls:\n" + "".join(l + "\n" for l in blade_walls(L, W)))
        f.write(f"tools:\n  - name: blade\n    mesh: {mesh}\n    contact: {{friction: 0.2}}\n    motion:\n"
                f"      interpolation: linear\n      keyframes:\n"
                f"        - {{time: 0.0, position: [0.0, 0.0, {bottom:.5f}], orientation: [1, 0, 0, 0]}}\n"
                f"        - {{time: {T:.6g}, position: [{BLADE['travel']}, 0.0, {bottom:.5f}], orientation: [1, 0, 0, 0]}}\n"
                f"particles:\n  checkpoint: {bed}\nrun:\n  duration: {T:.6g}\n"
                f"output:\n  file: {os.path.join(out, 'case.h5')}\n  particles_every: {T:.6g}\n"
                f"  wrenches_every: {max(dt, 0.005 / BLADE['speed']):.6g}\n  progress_every: 60\n")
    done = os.path.join(out, "case.done")
    if not os.path.exists(done):
        t0 = os.times()
        r = subprocess.run(["nice", os.path.join(REPO, "build", "bin", "dem_run"), case],
                           capture_output=True, text=True)
        t1 = os.times()
        open(os.path.join(out, "case.log"), "w").write(r.stdout + r.stderr)
        if r.returncode != 0:
            raise SystemExit(f"coarse_graining blade: the cut at {s:g}x failed: {r.stderr[-800:]}")
        cpu = (t1.children_user - t0.children_user) + (t1.children_system - t0.children_system)
        with open(done, "w") as f:
            json.dump({"cpu_seconds": cpu}, f)
    with open(done) as f:
        cpu = json.load(f)["cpu_seconds"]
    with h5py.File(os.path.join(out, "case.h5"), "r") as f:
        smp = f["/tools/blade/samples"][()]
    travel, draft = smp[:, 0] * BLADE["speed"], -smp[:, 1]
    mean = float(np.mean(draft[travel >= BLADE["steady_from"]]))
    print(f"    {s:g}x seed {seed}: {n} grains, surface {surf:.3f} m, draft {mean / 1e3:.2f} kN over "
          f"{BLADE['steady_from']}-{BLADE['travel']} m of travel, {cpu:.0f} CPU s", flush=True)
    return {"seed": seed, "grains": n, "surface_m": surf, "mean_N": mean, "cpu_seconds": cpu}


def blade_walls(L, W):
    return [f"  - {{name: floor, type: plane, point: [0, 0, 0], normal: [0, 0, 1]}}",
            f"  - {{name: back, type: plane, point: [-0.5, 0, 0], normal: [1, 0, 0], contact: {{friction: 0.0}}}}",
            f"  - {{name: front, type: plane, point: [{L}, 0, 0], normal: [-1, 0, 0], contact: {{friction: 0.0}}}}",
            f"  - {{name: side0, type: plane, point: [0, 0, 0], normal: [0, 1, 0], contact: {{friction: 0.0}}}}",
            f"  - {{name: side1, type: plane, point: [0, {W}, 0], normal: [0, -1, 0], contact: {{friction: 0.0}}}}"]

def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    pl = sub.add_parser("lab")
    pl.add_argument("--sizes", type=sizes_arg, default=[1.0, 1.5, 2.0, 3.0])
    pl.add_argument("--seeds", type=int, default=3)
    pl.add_argument("--jobs", type=int, default=1)
    pb = sub.add_parser("blade")
    pb.add_argument("--sizes", type=sizes_arg, default=[3.0, 2.0, 1.5, 1.0])
    pb.add_argument("--seeds", type=int, default=3)
    pc = sub.add_parser("chart")
    pc.add_argument("--study", default="results/coarse_graining/wheel_loader")
    args = p.parse_args()
    if args.cmd == "lab":
        if not (2 <= args.seeds <= 20):
            raise SystemExit("coarse_graining lab: --seeds must be 2..20 (an interval needs 2)")
        if not (1 <= args.jobs <= 8):
            raise SystemExit("coarse_graining lab: --jobs must be 1..8")
        return lab(args)
    if args.cmd == "blade":
        if not (2 <= args.seeds <= 20):
            raise SystemExit("coarse_graining blade: --seeds must be 2..20 (an interval needs 2)")
        return blade(args)
    return chart(args)


if __name__ == "__main__":
    sys.exit(main())
