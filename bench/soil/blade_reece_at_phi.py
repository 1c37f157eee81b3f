#!/usr/bin/python3
"""Reece's draft of the dry-sand blade cases at another friction angle (docs/soil_blade.md).

    /usr/bin/python3 bench/soil/blade_reece_at_phi.py --phi translating=DEG[:LO:HI] \
        --phi rotating=DEG[:LO:HI] [--cases FILE.csv] [--build build]

Reece's gamma term is F = gamma d^2 w N(phi, delta, alpha), with N the horizontal passive-wedge
coefficient of `soil_wedge` (the project's, independent of the DEM). For a case measured at
phi_tx the draft at another angle is F(phi_tx) N(phi) / N(phi_tx): the same bed, depth, width
and blade, only the angle changed. The DEM drafts are not rerun: CASES below are the dry-sand
tables of docs/soil_blade.md (2026-12-06), or --cases gives a CSV of the same columns. LO:HI
(optional) is the angle's interval; the ratio's interval follows from it.
"""
import argparse
import csv
import os
import re
import subprocess
import sys

DELTA = 11.31  # deg, atan(0.2): the blade friction of every case
# The dry-sand cases of docs/soil_blade.md (2026-12-06): the DEM's steady draft (kN, mean over the
# beds run) and Reece's draft at the triaxial angle phi_tx that table used (kN, deg).
COLUMNS = "material,model,depth_D,rake_deg,skim_D,dem_kN,reece_kN,phi_tx_deg"
CASES = """\
dry_sand,translating,4,90,1.0,14.00,6.08,34.35
dry_sand,translating,6,90,1.0,22.62,13.67,34.35
dry_sand,translating,10,90,1.0,56.54,38.30,34.35
dry_sand,translating,4,45,1.0,7.06,2.65,34.35
dry_sand,translating,6,45,1.0,11.55,5.96,34.35
dry_sand,translating,10,45,1.0,22.18,16.71,34.35
dry_sand,translating,4,90,0.25,10.89,6.08,34.35
dry_sand,translating,4,45,0.25,5.25,2.65,34.35
dry_sand_rotating,rotating,4,90,1.0,11.03,5.72,32.79
dry_sand_rotating,rotating,6,90,1.0,18.67,12.88,32.79
dry_sand_rotating,rotating,10,90,1.0,43.43,35.68,32.79
dry_sand_rotating,rotating,4,45,1.0,7.24,2.63,32.79
dry_sand_rotating,rotating,6,45,1.0,10.78,5.91,32.79
dry_sand_rotating,rotating,10,45,1.0,19.35,16.37,32.79
"""


def coefficient(build, phi, rake):
    r = subprocess.run([os.path.join(build, "bin", "soil_wedge"), "--phi", f"{phi}", "--delta",
                        f"{DELTA}", "--alpha", f"{rake}"], capture_output=True, text=True, check=True)
    return float(re.search(r"horizontal ([0-9.eE+-]+)", r.stdout).group(1))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default=None, help=f"a CSV with the columns {COLUMNS} (default: CASES)")
    p.add_argument("--build", default="build")
    p.add_argument("--phi", action="append", default=[],
                   help="MODEL=DEG or MODEL=DEG:LO:HI (translating, rotating), the angle to use")
    a = p.parse_args()
    phis = {}
    for item in a.phi:
        try:
            model, val = item.split("=")
            v = [float(x) for x in val.split(":")]
            if len(v) not in (1, 3) or not all(10 < x < 70 for x in v):
                raise ValueError
        except ValueError:
            sys.exit(f"blade_reece_at_phi: --phi {item!r}: give MODEL=DEG or MODEL=DEG:LO:HI, "
                     "angles in (10, 70) deg")
        phis[model] = v
    if not phis:
        sys.exit("blade_reece_at_phi: give at least one --phi MODEL=DEG")
    if a.cases:
        with open(a.cases) as f:
            rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    else:
        rows = list(csv.DictReader([COLUMNS] + CASES.splitlines()))
    print("material | depth | rake | skim | DEM kN | Reece at phi_tx kN | DEM/that | phi deg | "
          "Reece at phi kN | DEM/that [interval] | within 15 %")
    for r in rows:
        if r["model"] not in phis:
            continue
        v = phis[r["model"]]
        rake, phi_tx = float(r["rake_deg"]), float(r["phi_tx_deg"])
        dem, old = float(r["dem_kN"]), float(r["reece_kN"])
        n_tx = coefficient(a.build, phi_tx, rake)
        new = old * coefficient(a.build, v[0], rake) / n_tx
        ratio = dem / new
        span = ""
        if len(v) == 3:
            lo = dem / (old * coefficient(a.build, v[2], rake) / n_tx)
            hi = dem / (old * coefficient(a.build, v[1], rake) / n_tx)
            span = f" [{lo:.2f}, {hi:.2f}]"
        print(f"{r['material']} | {r['depth_D']} D | {rake:.0f} | {r['skim_D']} D | {dem:.2f} | {old:.2f} | "
              f"{dem / old:.2f} | {v[0]:.2f} | {new:.2f} | {ratio:.2f}{span} | "
              f"{'yes' if abs(ratio - 1) <= 0.15 else 'no'}")


if __name__ == "__main__":
    main()
