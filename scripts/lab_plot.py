#!/usr/bin/python3
"""Charts of the virtual lab tests (docs/soil_lab.md), from the CSVs dem_lab writes.

    /usr/bin/python3 scripts/lab_plot.py triaxial|biaxial|repose DIR

triaxial: DIR/triaxial.png (deviatoric stress and volumetric strain against axial strain, one
curve per confining pressure) and DIR/triaxial_mohr.png (Mohr circles at peak with the
Mohr-Coulomb envelope of triaxial_fit.csv). biaxial (plane strain): the same from
biaxial_*.csv as DIR/biaxial.png, with a third panel of the intermediate stress ratio
b = (sigma_2 - sigma_3) / (sigma_1 - sigma_3) on the fixed walls, and DIR/biaxial_mohr.png.
The dotted lines mark each test's peak. repose: DIR/repose.png (the heap's grains seen from the
side, the surface points and the fitted slope).
"""
import csv
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def triaxial(d, name="triaxial"):
    curves = rows(f"{d}/{name}_curves.csv")
    summary = rows(f"{d}/{name}_summary.csv")
    fit = {r["state"]: r for r in rows(f"{d}/{name}_fit.csv")}
    plane = name == "biaxial"
    by = {}
    for r in curves:
        by.setdefault(float(r["confining_Pa"]), []).append(r)
    if plane:
        fig, (a, b, c) = plt.subplots(3, 1, figsize=(7, 10), sharex=True)
    else:
        fig, (a, b) = plt.subplots(2, 1, figsize=(7, 8), sharex=True)
    peaks = {float(r["confining_Pa"]): float(r["peak_axial_strain"]) for r in summary}
    for k, (p, rs) in enumerate(sorted(by.items())):
        e = [100 * float(r["axial_strain"]) for r in rs]
        a.plot(e, [float(r["q_Pa"]) / 1e3 for r in rs], label=f"$\\sigma_3$ = {p / 1e3:g} kPa")
        b.plot(e, [-100 * float(r["volumetric_strain"]) for r in rs])
        if p in peaks:
            a.axvline(100 * peaks[p], color=f"C{k}", lw=0.6, ls=":")
        if plane:
            c.plot(e[1:], [(float(r["sigma2_Pa"]) - float(r["sigma3_Pa"])) /
                           max(float(r["sigma1_Pa"]) - float(r["sigma3_Pa"]), 1e-9) for r in rs[1:]])
    a.set_ylabel("deviatoric stress $\\sigma_1 - \\sigma_3$ [kPa]")
    a.legend()
    a.grid(alpha=0.3)
    b.set_ylabel("volumetric strain [%] (dilation positive)")
    b.grid(alpha=0.3)
    if plane:
        c.set_ylabel("b = $(\\sigma_2 - \\sigma_3) / (\\sigma_1 - \\sigma_3)$")
        c.set_ylim(-0.1, 1.0)
        c.grid(alpha=0.3)
        c.set_xlabel("axial strain [%]")
    else:
        b.set_xlabel("axial strain [%]")
    pk = fit.get("peak")
    title = "virtual biaxial (plane-strain) test" if plane else "virtual triaxial test"
    if pk:
        title += f": peak $\\varphi$ = {float(pk['phi_origin_deg']):.1f} deg"
    a.set_title(title)
    fig.tight_layout()
    fig.savefig(f"{d}/{name}.png", dpi=120)

    fig, ax = plt.subplots(figsize=(8, 5))
    smax = 0
    for r in summary:
        s1, s3 = float(r["sigma1_peak_Pa"]) / 1e3, float(r["sigma3_peak_Pa"]) / 1e3
        c, rad = (s1 + s3) / 2, (s1 - s3) / 2
        t = [i * math.pi / 100 for i in range(101)]
        ax.plot([c + rad * math.cos(x) for x in t], [rad * math.sin(x) for x in t],
                label=f"$\\sigma_3$ = {float(r['confining_Pa']) / 1e3:g} kPa, "
                      f"$\\varphi$ = {float(r['phi_peak_deg']):.1f} deg")
        smax = max(smax, s1)
    for state, style in (("peak", "k--"), ("critical", "k:"), ("end", "k:")):
        if state in fit:
            phi = math.radians(float(fit[state]["phi_origin_deg"]))
            ax.plot([0, smax], [0, smax * math.tan(phi)], style,
                    label=f"{state} envelope, $\\varphi$ = {math.degrees(phi):.1f} deg")
    if "peak" in fit and len(summary) >= 2:
        phi = math.radians(float(fit["peak"]["phi_deg"]))
        c = float(fit["peak"]["cohesion_Pa"]) / 1e3
        ax.plot([0, smax], [c, c + smax * math.tan(phi)], "C7-.",
                label=f"peak fit with intercept: $\\varphi$ = {math.degrees(phi):.1f} deg, c = {c:.1f} kPa")
    ax.set_xlabel("normal stress [kPa]")
    ax.set_ylabel("shear stress [kPa]")
    ax.set_aspect("equal")
    ax.set_xlim(0, smax * 1.05)
    ax.set_ylim(0, smax * 0.6)
    ax.legend(fontsize=8)
    ax.set_title("Mohr circles (sigma_1, sigma_3) at peak" + (", plane strain" if plane else ""))
    fig.tight_layout()
    fig.savefig(f"{d}/{name}_mohr.png", dpi=120)


def repose(d):
    g = rows(f"{d}/repose_grains.csv")
    sfc = rows(f"{d}/repose_surface.csv")
    s = rows(f"{d}/repose_summary.csv")[0]
    fig, ax = plt.subplots(figsize=(9, 5))
    ax.scatter([math.hypot(float(r["x"]), float(r["y"])) for r in g], [float(r["z"]) for r in g],
               s=2, c="0.6", label="grains (radius from the axis)")
    used = [r for r in sfc if r["used"] == "1" and r["sector"] == "-1"]
    ax.scatter([float(r["radius_m"]) for r in used], [float(r["height_m"]) for r in used], s=8,
               c="C0", label="surface (highest grain per ring) in the fit")
    a, h0 = float(s["angle_deg"]), float(s["intercept_m"])
    rmax = h0 / math.tan(math.radians(a)) if a > 0 else 0
    ax.plot([0, rmax], [h0, 0], "C3", label=f"fit: {a:.1f} +- {float(s['angle_sector_sd_deg']):.1f} deg")
    ax.set_xlabel("radius [m]")
    ax.set_ylabel("height above the base [m]")
    ax.set_aspect("equal")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1))
    ax.set_title("angle of repose (lifted cylinder)")
    fig.tight_layout()
    fig.savefig(f"{d}/repose.png", dpi=120)


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("triaxial", "biaxial", "repose"):
        sys.exit("usage: lab_plot.py triaxial|biaxial|repose DIR")
    if sys.argv[1] == "repose":
        repose(sys.argv[2])
    else:
        triaxial(sys.argv[2], sys.argv[1])
