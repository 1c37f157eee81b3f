#!/usr/bin/python3
"""Study of the virtual triaxial test (docs/soil_lab.md; not in CI): the peak friction angle
against the contact friction mu and the stiffness ratio k_T/k_N, each point an ensemble of
samples (seeds) with a 95 % interval, and the sample-size check (the angle at twice the grains
stays inside the scatter).

    /usr/bin/python3 scripts/lab_study.py [--mu 0.2,0.4,0.6,0.8] [--kt 0.25,0.5,1.0]
        [--seeds 3] [--grains 500] [--strain 0.08] [--pressure 10.0e3]
        [--config configs/lab/triaxial.yaml] [--out results/lab_study] [--exe build/bin/dem_lab]
        [--rolling MU_R]

--rolling MU_R runs the rotating particle model (grains.model: rotating) with an EPSD rolling
resistance of friction MU_R and damping 0.3 (docs/soil_models.md); without it the grains
translate (the default model). Its runs are cached under their own names (_mr<MU_R>).

Each run is one `dem_lab triaxial` at one confining pressure (phi from sin(phi) = (s1 - s3) /
(s1 + s3) at the peak, the cohesionless reading; the three-pressure fit is the command's own).
It prints a table and writes OUT/study.csv, OUT/size.csv and OUT/friction_angle.png.
Runs are cached: a run whose summary exists is not repeated (delete OUT to start over).
"""
import argparse
import csv
import math
import os
import statistics
import subprocess
import sys

# Student t, two-sided 95 %, by degrees of freedom.
T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262}


def run(args, name, sets):
    if args.rolling is not None:  # the rotating model: its own cache names and keys
        name += f"_mr{args.rolling:g}"
        sets = sets + ["grains.model=rotating",
                       f"grains.rolling_resistance={{friction: {args.rolling}, damping: 0.3}}"]
    out = os.path.join(args.out, name)
    summary = os.path.join(out, "triaxial_summary.csv")
    if not os.path.exists(summary):
        cmd = ["nice", args.exe, "triaxial", args.config, "--out", out, "--no-plot",
               "--set", f"triaxial.confining_pressures=[{args.pressure}]",
               "--set", f"triaxial.max_axial_strain={args.strain}"]
        for s in sets:
            cmd += ["--set", s]
        print(" ".join(cmd), file=sys.stderr, flush=True)
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if r.returncode != 0:
            sys.exit(f"run {name} failed ({r.returncode}):\n{r.stderr[-2000:]}")
    with open(summary, newline="") as f:
        return next(csv.DictReader(f))


def interval(values):
    m = statistics.mean(values)
    if len(values) < 2:
        return m, 0.0, 0.0
    sd = statistics.stdev(values)
    return m, sd, T95.get(len(values) - 1, 2.0) * sd / math.sqrt(len(values))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mu", default="0.2,0.4,0.6,0.8")
    p.add_argument("--kt", default="0.25,0.5,1.0")
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--grains", type=int, default=500)
    p.add_argument("--strain", type=float, default=0.08)
    p.add_argument("--pressure", default="10.0e3")
    p.add_argument("--config", default="configs/lab/triaxial.yaml")
    p.add_argument("--out", default="results/lab_study")
    p.add_argument("--exe", default="build/bin/dem_lab")
    p.add_argument("--rolling", type=float, default=None,
                   help="rotating grains with this EPSD rolling friction mu_r (0 < mu_r <= 1)")
    args = p.parse_args()
    if args.rolling is not None and not 0 < args.rolling <= 1:
        sys.exit(f"--rolling: {args.rolling} must be in (0, 1] (mu_r, docs/soil_models.md)")
    if args.seeds < 2:
        sys.exit("--seeds: give at least 2 (an interval needs a scatter)")
    mus = [float(v) for v in args.mu.split(",")]
    kts = [float(v) for v in args.kt.split(",")]
    os.makedirs(args.out, exist_ok=True)

    rows = []
    for kt in kts:
        for mu in mus:
            phis, packs = [], []
            for seed in range(1, args.seeds + 1):
                s = run(args, f"n{args.grains}_mu{mu}_kt{kt}_s{seed}",
                        [f"sample.count={args.grains}", f"sample.seed={seed}",
                         f"grains.contact.friction={mu}",
                         f"grains.contact.tangential_stiffness_ratio={kt}"])
                phis.append(float(s["phi_peak_deg"]))
                packs.append(float(s["packing_inner"]))
            m, sd, ci = interval(phis)
            rows.append(dict(mu=mu, kt=kt, grains=args.grains, n=len(phis), phi_mean=m, phi_sd=sd,
                             phi_ci95=ci, phi_min=min(phis), phi_max=max(phis),
                             packing_inner=statistics.mean(packs)))
    with open(os.path.join(args.out, "study.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    model = "translating" if args.rolling is None else f"rotating, mu_r {args.rolling:g}"
    print(f"peak friction angle ({model}), {args.grains} grains, sigma3 {float(args.pressure) / 1e3:g} kPa, "
          f"{args.seeds} samples each (mean +- 95 % interval [min, max]):")
    print("  k_T/k_N   mu    phi_peak [deg]")
    for r in rows:
        print(f"  {r['kt']:6.2f}  {r['mu']:4.2f}  {r['phi_mean']:6.2f} +- {r['phi_ci95']:4.2f}"
              f"  [{r['phi_min']:.2f}, {r['phi_max']:.2f}]")

    # Sample size: the middle mu and k_T/k_N of the grid at the grains and twice as many.
    mu, kt = mus[len(mus) // 2], kts[len(kts) // 2]
    size = []
    for n in (args.grains, 2 * args.grains):
        phis = []
        for seed in range(1, args.seeds + 1):
            s = run(args, f"n{n}_mu{mu}_kt{kt}_s{seed}",
                    [f"sample.count={n}", f"sample.seed={seed}", f"grains.contact.friction={mu}",
                     f"grains.contact.tangential_stiffness_ratio={kt}"])
            phis.append(float(s["phi_peak_deg"]))
        m, sd, ci = interval(phis)
        size.append(dict(grains=n, mu=mu, kt=kt, n=len(phis), phi_mean=m, phi_sd=sd, phi_ci95=ci,
                         phi_min=min(phis), phi_max=max(phis)))
    with open(os.path.join(args.out, "size.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(size[0]))
        w.writeheader()
        w.writerows(size)
    a, b = size
    diff = b["phi_mean"] - a["phi_mean"]
    scatter = max(a["phi_sd"], b["phi_sd"])
    print(f"sample size (mu {mu}, k_T/k_N {kt}): {a['grains']} grains {a['phi_mean']:.2f} +- "
          f"{a['phi_ci95']:.2f} deg (sd {a['phi_sd']:.2f}), {b['grains']} grains {b['phi_mean']:.2f} +- "
          f"{b['phi_ci95']:.2f} deg (sd {b['phi_sd']:.2f}): moved {diff:+.2f} deg, "
          + ("inside" if abs(diff) <= 2 * scatter else "BEYOND") + " twice the larger sd")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 5))
    for kt in kts:
        rs = [r for r in rows if r["kt"] == kt]
        ax.errorbar([r["mu"] for r in rs], [r["phi_mean"] for r in rs],
                    yerr=[r["phi_ci95"] for r in rs], marker="o", capsize=3, label=f"k_T/k_N = {kt:g}")
    ax.set_xlabel("contact friction $\\mu$")
    ax.set_ylabel("peak friction angle [deg]")
    ax.set_title(f"virtual triaxial, {args.grains} grains, $\\sigma_3$ = {float(args.pressure) / 1e3:g} kPa, "
                 f"{args.seeds} samples (95 % intervals)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "friction_angle.png"), dpi=120)


if __name__ == "__main__":
    main()
