#!/usr/bin/python3
"""The hauler's first seconds of tipping with each particle model (docs/soil_models.md).

    /usr/bin/python3 scripts/hauler_models.py [--end 3] [--members 2] [--out results/hauler_models]
        [--models translating,rotating] [--rolling 0.1] [--rolling-damping 0.3] [--dt-rotating 1.25e-4]
        [--analyse-only] [--config configs/hauler.yaml]

Runs `cosim_master configs/hauler.yaml` (hauler_adapter + dem_service, the prepared load of
results/hauler_load.h5; run scripts/run_hauler.sh once first; --config configs/hauler_lattice.yaml:
the lattice load of before issue 43, results/hauler_load_lattice.h5) up to --end seconds for each
model and ensemble member (members differ by particles.perturb.seed, amplitude 1e-6 m), with the
soil's particle snapshots every 0.02 s, then compares, over windows of 0.5 s, the soil's torque on
the dump body about its hinge (the recorded wrench) with what the load's weight and angular
momentum give while the body is the only thing the load touches:

    tau_expected = sum_i (x_i - r) x m_i g - dL_r/dt - v_r x P,
    L_r = sum_i m_i (x_i - r) x v_i + I_i w_i,  P = sum_i m_i v_i

(r the hinge's world position, the wrench's reference point; dL_r/dt from the snapshots at the
window's ends, the weight torque averaged over its snapshots). It prints a markdown table per
model: window, measured and expected torque about y (kN m), the excess in %, and the front axle's
vertical force (TYDEX C, 0.05 s moving average) at 1, 1.5, 2, 2.5 and 3 s with the members' range.
The rotating model runs with particles.rolling_resistance {model: epsd, friction: --rolling,
damping: --rolling-damping} and scene.dt = --dt-rotating (its tangential contact period with free
spins is shorter: docs/physics.md "Rotation").
"""
import argparse
import os
import subprocess
import sys

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
G = np.array([0.0, 0.0, -9.81])
DENSITY = 2600.0  # the grains' density when the soil's record does not give it (density())


def density(soil_h5):
    """The grains' density from the resolved config the soil stored (materials.<name>.density;
    a material file is resolved into it), else DENSITY."""
    with h5py.File(soil_h5, "r") as f:
        text = f.attrs.get("config", b"")
    text = text.decode() if isinstance(text, bytes) else str(text)
    try:
        import yaml
        mats = (yaml.safe_load(text) or {}).get("materials", {})
        values = {float(m["density"]) for m in mats.values() if isinstance(m, dict) and "density" in m}
        if len(values) == 1:
            return values.pop()
    except Exception:  # noqa: BLE001 - an unreadable record falls back to the default
        pass
    return DENSITY


def run(model, seed, a):
    name = f"{model}_{seed}"
    out = os.path.join(a.out, name)
    sets = [f"time.end={a.end}", f"output.file={out}.h5", f"output.csv={out}.csv",
            "output.progress=off",
            f"participants.soil.parameters.output.file={out}_soil.h5",
            "participants.soil.parameters.output.particles_every=0.02",
            "participants.soil.parameters.particles.perturb.amplitude=1.0e-6",
            f"participants.soil.parameters.particles.perturb.seed={seed}",
            f"participants.soil.parameters.particles.model={model}"]
    if model == "rotating":
        sets += [f"participants.soil.parameters.particles.rolling_resistance.friction={a.rolling}",
                 f"participants.soil.parameters.particles.rolling_resistance.damping={a.rolling_damping}",
                 f"participants.soil.parameters.scene.dt={a.dt_rotating}"]
    cmd = [os.path.join(ROOT, "build/bin/cosim_master"), os.path.join(ROOT, a.config)]
    for s in sets:
        cmd += ["--set", s]
    print("hauler_models:", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT)
    return out


def smooth(t, y, width):
    dt = t[1] - t[0]
    k = max(1, int(round(width / dt)))
    return np.convolve(y, np.ones(k) / k, mode="same")


def analyse(out):
    with h5py.File(out + ".h5", "r") as f:
        t = f["time"][:]
        w = f["participants/soil/outputs/body"][:].reshape(len(t), -1)
        fz = f["participants/hauler/outputs/front_fz"][:].reshape(len(t), -1)[:, 0]
    snaps = []
    rho = density(out + "_soil.h5")
    with h5py.File(out + "_soil.h5", "r") as f:
        for name in f["particles"]:
            g = f["particles"][name]
            x, v, r = g["position"][:], g["velocity"][:], g["radius"][:]
            om = g["angular_velocity"][:] if "angular_velocity" in g else np.zeros_like(x)
            snaps.append((float(g.attrs["time"]), x, v, r, om))
    snaps.sort(key=lambda s: s[0])
    ts = np.array([s[0] for s in snaps])
    # the hinge (wrench reference point) at the snapshot times, and its velocity
    ref = np.stack([np.interp(ts, t, w[:, 6 + k]) for k in range(3)], axis=1)
    vref = np.gradient(ref, ts, axis=0)
    W, L, P = [], [], []
    for k, (_, x, v, r, om) in enumerate(snaps):
        m = rho * 4.0 / 3.0 * np.pi * r ** 3
        arm = x - ref[k]
        W.append(np.cross(arm, m[:, None] * G).sum(axis=0))
        L.append((m[:, None] * np.cross(arm, v)).sum(axis=0) + ((0.4 * m * r * r)[:, None] * om).sum(axis=0))
        P.append((m[:, None] * v).sum(axis=0))
    W, L, P = np.array(W), np.array(L), np.array(P)
    rows = []
    for t0 in np.arange(0.5, ts[-1] - 1e-9, 0.5):
        t1 = t0 + 0.5
        a, b = np.searchsorted(ts, t0 - 1e-9), np.searchsorted(ts, t1 + 1e-9) - 1
        if b <= a:
            continue
        expected = W[a:b + 1].mean(axis=0) - (L[b] - L[a]) / (ts[b] - ts[a]) \
            - np.cross(vref[a:b + 1], P[a:b + 1]).mean(axis=0)
        sel = (t > ts[a]) & (t <= ts[b])
        measured = w[sel, 3:6].mean(axis=0)
        rows.append((ts[a], ts[b], measured[1], expected[1]))
    fzs = smooth(t, fz, 0.05)
    front = {tt: float(np.interp(tt, t, fzs)) for tt in (1.0, 1.5, 2.0, 2.5, 3.0) if tt <= t[-1] - 0.025}
    return rows, front


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--end", type=float, default=3.0)
    ap.add_argument("--members", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "results/hauler_models"))
    ap.add_argument("--models", default="translating,rotating")
    ap.add_argument("--rolling", type=float, default=0.1)
    ap.add_argument("--rolling-damping", type=float, default=0.3)
    ap.add_argument("--dt-rotating", type=float, default=1.25e-4)
    ap.add_argument("--analyse-only", action="store_true")
    ap.add_argument("--config", default="configs/hauler.yaml", help="the hauler scene (relative to the repo)")
    a = ap.parse_args()
    if not os.path.exists(os.path.join(ROOT, a.config)):
        sys.exit(f"hauler_models: --config {a.config}: no such file")
    if a.config == "configs/hauler.yaml" and not os.path.exists(os.path.join(ROOT, "results/hauler_load.h5")):
        sys.exit("hauler_models: results/hauler_load.h5 is missing; run scripts/run_hauler.sh once")
    os.makedirs(a.out, exist_ok=True)
    for model in a.models.split(","):
        results = []
        for seed in range(1, a.members + 1):
            out = os.path.join(a.out, f"{model}_{seed}")
            if not a.analyse_only:
                run(model, seed, a)
            results.append(analyse(out))
        print(f"\n{model} ({len(results)} members): soil torque on the body about the hinge (y)")
        print("| window [s] | measured [kN m] | weight + momentum [kN m] | excess [%] |")
        print("| --- | --- | --- | --- |")
        for k, row in enumerate(results[0][0]):
            meas = [r[0][k][2] / 1e3 for r in results]
            exp = [r[0][k][3] / 1e3 for r in results]
            exc = [100 * (mm / ee - 1) for mm, ee in zip(meas, exp)]
            print(f"| {row[0]:.2f}-{row[1]:.2f} | {np.mean(meas):.1f} ({min(meas):.1f}..{max(meas):.1f}) | "
                  f"{np.mean(exp):.1f} ({min(exp):.1f}..{max(exp):.1f}) | "
                  f"{np.mean(exc):+.1f} ({min(exc):+.1f}..{max(exc):+.1f}) |")
        print("front axle F_z [kN]: " + ", ".join(
            f"{tt:.1f} s {np.mean([r[1][tt] for r in results]) / 1e3:.1f} "
            f"({min(r[1][tt] for r in results) / 1e3:.1f}..{max(r[1][tt] for r in results) / 1e3:.1f})"
            for tt in sorted(results[0][1])))


if __name__ == "__main__":
    main()
