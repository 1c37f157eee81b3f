#!/usr/bin/python3
"""The wheel loader's bucket turning through its curl in the dry-sand pile, with each particle
model (docs/soil_blade.md "The bucket's curl").

    /usr/bin/python3 bench/soil/bucket_curl.py [--out results/bucket_curl] [--build build]
        [--models translating,rotating] [--rolling-friction 0.1] [--rolling-damping 0.3]
        [--material configs/materials/dry_sand.yaml] [--jobs 2] [--members 1] [--fresh]
        [--analyse-only]

Runs `dem_run configs/soil/curl_dry_sand.yaml` (the prepared dry-sand pile of
scripts/prepare_pile_dry_sand.sh, cut at x = 9 m by configs/soil/curl_dry_sand_cut.yaml; the
bucket's mesh of the wheel_loader_meshes target, moved by keyframes: penetration, a curl in the
pile, a lift out, a hold, a curl with the load held clear of the pile, a hold) once per particle
model and member (`--material FILE`: the grains' law from another material file of the same
grains, e.g. the calibrated rotating dry sand configs/materials/dry_sand_rotating.yaml, on the
same pile; a rotating material's own rolling resistance unless --rolling-friction is given;
member k > 1 perturbs every grain by up to 1e-6 m with seed k; a complete
output is reused unless --fresh), and compares the soil's torque on the bucket about
its A-pin (the recorded wrench, about y) with what the load's weight and angular momentum give:

    tau_expected = sum_i (x_i - r) x m_i g - (L_r(t1) - L_r(t0)) / (t1 - t0),
    L_r = sum_i m_i (x_i - r) x v_i + I_i w_i   (I_i = 2/5 m_i r_i^2; w = 0 without rotation)

for the load S: every grain whose centre is above --load-above (m) at the window's start (the
pile stands 1.2 m high; the lifted bucket holds its load above 1.9 m). r is the A-pin, fixed in
every window (the lift is outside them). The balance holds while S touches nothing but the
bucket and itself: the script checks, at every snapshot of the window, that no grain of S
overlaps a grain outside S or a wall, and says so. Windows:

  curl in the pile   1.6-2.4 s   the bucket turns 0 -> 35 deg through the pile (no reference:
                                 the pile pushes too; the two models against each other)
  held, at rest      4.3-4.7 s   the check of the method: the torque is the load's weight torque
  curl, load held    4.8-5.6 s   35 -> 55 deg at 0.35 rad/s, clear of the pile
  held after         5.75-6.0 s

It prints one table per model and writes OUT/bucket_curl.csv and the chart OUT/bucket_curl.png
(the torque against time with each model).
"""
import argparse
import csv
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIG = os.path.join(ROOT, "configs", "soil", "curl_dry_sand.yaml")
G = np.array([0.0, 0.0, -9.81])
WINDOWS = [("curl in the pile", 1.6, 2.4, False), ("held, at rest", 4.3, 4.7, True),
           ("curl, load held", 4.8, 5.6, True), ("held after", 5.75, 6.0, True)]


DEFAULT_MATERIAL = os.path.join(ROOT, "configs", "materials", "dry_sand.yaml")


def load_material(path):
    """The material file's density, radii and rolling resistance (None if it names none)."""
    import yaml
    try:
        with open(path) as f:
            m = yaml.safe_load(f)
    except OSError as e:
        sys.exit(f"bucket_curl: --material {path}: {e.strerror}")
    if not isinstance(m, dict) or "density" not in m or "radius" not in m:
        sys.exit(f"bucket_curl: --material {path}: not a material file (no density or radius; "
                 "configs/materials/*.yaml)")
    with open(DEFAULT_MATERIAL) as f:
        pile = yaml.safe_load(f)
    if float(m["density"]) != float(pile["density"]) or m["radius"] != pile["radius"]:
        sys.exit(f"bucket_curl: --material {path}: its grains (density {m['density']}, radius "
                 f"{m['radius']}) are not the pile's ({pile['density']}, {pile['radius']}, "
                 "configs/materials/dry_sand.yaml); the curl loads that pile")
    parts = m.get("particles") or {}
    rr = parts.get("rolling_resistance") if parts.get("model") == "rotating" else None
    return float(m["density"]), rr


def name(model, member):
    return f"curl_{model}" + ("" if member == 1 else f"_m{member}")


def complete(h5):
    import h5py
    try:
        with h5py.File(h5, "r") as f:
            return int(f.attrs.get("complete", 0)) == 1
    except OSError:
        return False


def run(model, member, a):
    out = os.path.join(a.out, name(model, member) + ".h5")
    if not a.fresh and complete(out):
        print(f"bucket_curl: {out} exists (--fresh runs it again)", flush=True)
        return out
    sets = [f"output.file={out}", f"particles.model={model}"]
    if os.path.abspath(a.material) != DEFAULT_MATERIAL:
        sets.append("materials.soil.file=" + os.path.relpath(os.path.abspath(a.material), os.path.dirname(CONFIG)))
    if member > 1:   # ensemble members: a seeded shift of every grain by up to 1e-6 m
        sets.append(f"particles.perturb={{amplitude: 1.0e-6, seed: {member}}}")
        # the shift pushes a contact past the bed's recorded largest overlap (1.25 %)
        sets.append("scene.stability.overlap_tolerance=0.02")
    if model == "rotating":
        sets.append("particles.rolling_resistance={model: epsd, friction: %g, damping: %g}"
                    % (a.rolling_friction, a.rolling_damping))
    cmd = ["nice", os.path.join(a.build, "bin", "dem_run"), CONFIG]
    for s in sets:
        cmd += ["--set", s]
    log = os.path.join(a.out, name(model, member) + ".log")
    print("bucket_curl:", " ".join(cmd[1:]), flush=True)
    with open(log, "w") as f:
        r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT)
    if r.returncode != 0:
        sys.exit(f"bucket_curl: dem_run failed ({r.returncode}); see {log}")
    return out


def snapshots(h5, density):
    import h5py
    snaps = []
    with h5py.File(h5, "r") as f:
        if int(f.attrs.get("complete", 0)) != 1:
            sys.exit(f"bucket_curl: {h5} is incomplete")
        s = f["/tools/bucket/samples"][()]
        for name in f["particles"]:
            g = f["particles"][name]
            x, v, r = g["position"][()], g["velocity"][()], g["radius"][()]
            om = g["angular_velocity"][()] if "angular_velocity" in g else np.zeros_like(x)
            ids = g["id"][()] if "id" in g else np.arange(len(x))
            snaps.append((float(g.attrs["time"]), ids, x, v, r, om))
    snaps.sort(key=lambda q: q[0])
    return s, snaps


def touches_outside(x, r, inside, walls_y=1.9):
    """Grains of S (inside) overlapping a grain outside S, the ground or a side wall."""
    xs, rs = x[inside], r[inside]
    bad = int(np.sum(xs[:, 2] - rs <= 0) + np.sum(np.abs(xs[:, 1]) + rs >= walls_y))
    out = ~inside & (x[:, 2] > xs[:, 2].min() - 0.3) if inside.any() else ~inside
    xo, ro = x[out], r[out]
    for i in range(len(xs)):
        d = np.linalg.norm(xo - xs[i], axis=1) - ro - rs[i]
        bad += int(np.sum(d < 0))
    return bad


def analyse(h5, density, load_above):
    s, snaps = snapshots(h5, density)
    t, my = s[:, 0], s[:, 5]
    ts = np.array([q[0] for q in snaps])
    rows = []
    for label, t0, t1, check in WINDOWS:
        a, b = int(np.searchsorted(ts, t0 - 1e-9)), int(np.searchsorted(ts, t1 + 1e-9)) - 1
        if b <= a:
            continue
        ref = s[np.searchsorted(t, ts[a]), 7:10]          # the A-pin (fixed in the window)
        ids0 = snaps[a][1]
        load = set(ids0[snaps[a][2][:, 2] > load_above].tolist())
        W, L, mass, touching = [], [], 0.0, 0
        for k in range(a, b + 1):
            _, ids, x, v, r, om = snaps[k]
            inside = np.array([i in load for i in ids.tolist()])
            m = density * 4.0 / 3.0 * np.pi * r ** 3
            arm = x[inside] - ref
            W.append(np.cross(arm, m[inside, None] * G).sum(axis=0))
            L.append((m[inside, None] * np.cross(arm, v[inside])).sum(axis=0)
                     + ((0.4 * m * r * r)[inside, None] * om[inside]).sum(axis=0))
            if k == a:
                mass = float(m[inside].sum())
            if check:
                touching = max(touching, touches_outside(x, r, inside))
        W, L = np.array(W), np.array(L)
        weight = float(W.mean(axis=0)[1])
        dldt = float((L[-1] - L[0])[1] / (ts[b] - ts[a]))
        sel = (t > ts[a]) & (t <= ts[b])
        measured = float(my[sel].mean())
        rows.append(dict(window=label, t0=ts[a], t1=ts[b], load_t=mass / 1000, grains=len(load),
                         measured_kNm=measured / 1e3, weight_kNm=weight / 1e3, dLdt_kNm=dldt / 1e3,
                         expected_kNm=(weight - dldt) / 1e3,
                         excess=(measured / (weight - dldt) - 1) if check else float("nan"),
                         touching=touching if check else -1))
    return rows, t, my


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=os.path.join(ROOT, "results", "bucket_curl"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--models", default="translating,rotating")
    p.add_argument("--rolling-friction", type=float, default=None,
                   help="rotating model: EPSD mu_r (default: the material's, else 0.1)")
    p.add_argument("--rolling-damping", type=float, default=None,
                   help="rotating model: EPSD damping (default: the material's, else 0.3)")
    p.add_argument("--material", default=DEFAULT_MATERIAL,
                   help="material file of the grains' law (the pile's grains; default the dry sand)")
    p.add_argument("--load-above", type=float, default=1.9,
                   help="m: the load is the grains whose centre is above this at a window's start")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--members", type=int, default=1,
                   help="runs per model: member 1 as configured, member k > 1 with particles.perturb seed k (1e-6 m)")
    p.add_argument("--fresh", action="store_true", help="run again even when a complete output exists")
    p.add_argument("--analyse-only", action="store_true")
    a = p.parse_args()
    density, rolling = load_material(a.material)
    if a.rolling_friction is None:
        a.rolling_friction = float(rolling["friction"]) if rolling else 0.1
    if a.rolling_damping is None:
        a.rolling_damping = float(rolling.get("damping", 0.3)) if rolling else 0.3
    models = a.models.split(",")
    if any(m not in ("translating", "rotating") for m in models) or not models:
        sys.exit("bucket_curl: --models is a comma-separated list of translating, rotating")
    if not (0 < a.rolling_friction <= 1) or not (0 <= a.rolling_damping <= 1):
        sys.exit("bucket_curl: --rolling-friction must lie in (0, 1], --rolling-damping in [0, 1]")
    if a.jobs < 1:
        sys.exit("bucket_curl: --jobs must be >= 1")
    if not 1 <= a.members <= 20:
        sys.exit("bucket_curl: --members must lie in 1..20")
    runs = [(m, k) for k in range(1, a.members + 1) for m in models]
    print(f"bucket_curl: material {os.path.relpath(os.path.abspath(a.material), ROOT)}"
          + (f"; rotating model with rolling friction {a.rolling_friction}, damping {a.rolling_damping}"
             if "rotating" in models else ""), flush=True)
    a.out, a.build = os.path.abspath(a.out), os.path.abspath(a.build)
    os.makedirs(a.out, exist_ok=True)
    if not a.analyse_only:
        if not os.path.exists(os.path.join(ROOT, "results", "pile_dry_sand.h5")):
            subprocess.run(["nice", "bash", os.path.join(ROOT, "scripts", "prepare_pile_dry_sand.sh")], check=True)
        if not os.path.exists(os.path.join(ROOT, "results", "pile_dry_sand_cut.h5")):
            subprocess.run(["nice", os.path.join(a.build, "bin", "dem_run"),
                            os.path.join(ROOT, "configs", "soil", "curl_dry_sand_cut.yaml")], check=True, cwd=ROOT)
        if not os.path.exists(os.path.join(a.build, "meshes", "bucket_r1.stl")):
            subprocess.run(["cmake", "--build", a.build, "--target", "wheel_loader_meshes"], check=True)
        with ThreadPoolExecutor(a.jobs) as ex:
            files = dict(zip(runs, ex.map(lambda mk: run(mk[0], mk[1], a), runs)))
    else:
        files = {(m, k): os.path.join(a.out, name(m, k) + ".h5") for m, k in runs}
        missing = [f for f in files.values() if not os.path.exists(f)]
        if missing:
            sys.exit(f"bucket_curl: --analyse-only, but {missing[0]} does not exist (run without "
                     "--analyse-only, or give the --out, --models and --members of that run)")
    allrows, curves = [], {}
    for m, k in runs:
        rows, t, my = analyse(files[(m, k)], density, a.load_above)
        if k == 1:
            curves[m] = (t, my)
        print(f"\n{m}, member {k}" + (f" (rolling friction {a.rolling_friction}, damping {a.rolling_damping})" if m == "rotating" else ""))
        print("| window | s | load t (grains) | soil torque on the bucket kN m | weight torque kN m | dL/dt kN m "
              "| weight - dL/dt kN m | excess | grains of the load touching pile or walls |")
        print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
        for r in rows:
            ex = f"{100 * r['excess']:+.1f} %" if r["excess"] == r["excess"] else "(no reference)"
            tc = str(r["touching"]) if r["touching"] >= 0 else ""
            print(f"| {r['window']} | {r['t0']:.2f}-{r['t1']:.2f} | {r['load_t']:.2f} ({r['grains']}) | "
                  f"{r['measured_kNm']:.1f} | {r['weight_kNm']:.1f} | {r['dLdt_kNm']:.1f} | "
                  f"{r['expected_kNm']:.1f} | {ex} | {tc} |")
            allrows.append(dict(model=m, member=k, **r))
    print("\nthe curl with the load held, excess over the load's weight and momentum per member:")
    for m in models:
        ex = [r["excess"] for r in allrows if r["model"] == m and r["window"] == "curl, load held"]
        print(f"  {m}: " + ", ".join(f"{100 * e:+.1f} %" for e in ex)
              + (f"; mean {100 * np.mean(ex):+.1f} %" if len(ex) > 1 else ""))
    with open(os.path.join(a.out, "bucket_curl.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(allrows[0].keys()))
        w.writeheader()
        w.writerows(allrows)
    plot(a.out, curves)


def plot(out, curves):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    for ax, (lo, hi) in zip(axes, [(0, None), (WINDOWS[0][1] + 0.05, None)]):
        for m, (t, my) in curves.items():
            k = max(1, int(round(0.05 / (t[1] - t[0]))))
            tt, mm = t[k - 1:], np.convolve(my, np.ones(k) / k, mode="valid") / 1e3
            sel = tt >= lo
            ax.plot(tt[sel], mm[sel], lw=0.9, label=m)
        for label, t0, t1, _ in WINDOWS:
            ax.axvspan(t0, t1, color="0.92", zorder=0)
            ax.text((t0 + t1) / 2, 0.02, label, transform=ax.get_xaxis_transform(), ha="center", fontsize=7)
        ax.set_xlabel("time (s)")
        ax.legend()
    axes[0].set_ylabel("soil torque on the bucket about the A-pin, y (kN m; 0.05 s mean)")
    axes[0].set_title("the whole run (penetration: the pile's push)", fontsize=9)
    axes[1].set_title("from the curl in the pile on", fontsize=9)
    fig.tight_layout()
    png = os.path.join(out, "bucket_curl.png")
    fig.savefig(png, dpi=120)
    print("chart:", png)


if __name__ == "__main__":
    main()
