#!/usr/bin/python3
"""The wheel loader's outputs at other inner steps against a reference inner step, stepped alone
on the same recorded soil wrench (bench/mbs/loader_alone --out files): the largest and RMS
deviation of the bucket's pose and twist, the bearing and cylinder forces, over the whole run
and over the part with soil on the bucket (docs/performance.md, "The loader alone").

    /usr/bin/python3 bench/mbs/inner_step_error.py REF.f64 OTHER.f64 [OTHER.f64 ...] [--wrench W.f64]

The files: loader_alone --out at --macro 1e-3 (the soil work assumes 1 ms steps).
"""
import sys

import numpy as np

COLS = ["a_long", "a_vert", "boom_angle"] + [f"bucket{i}" for i in range(13)] + [
    "bucket_pitch", "drive_force", "edge_x", "edge_z", "j_long", "j_vert", "lift_force", "normal_load",
    "speed", "tilt_force", "x_machine", "normal_front", "normal_rear", "lift_length", "tilt_length"]


def load(path):
    v = np.fromfile(path, dtype="<f8")
    if v.size % len(COLS):
        sys.exit(f"inner_step_error: {path}: not {len(COLS)} float64 per step (loader_alone --average 0 --out)")
    return v.reshape(-1, len(COLS))


def quat_angle(q1, q2):
    """Angle of the rotation between two orientations [w x y z]: 2 atan2(|vec(q1* q2)|, |w|)."""
    w1, v1, w2, v2 = q1[:, 0], q1[:, 1:], q2[:, 0], q2[:, 1:]
    w = w1 * w2 + np.sum(v1 * v2, axis=1)
    v = w1[:, None] * v2 - w2[:, None] * v1 - np.cross(v1, v2)
    return 2 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(w))


def soil_work(o, w, dt):
    """Work of the soil's wrench on the bucket [J]: sum over steps of (F . v(r) + T . omega) dt with
    the step's constant wrench (torque about r) and the bucket's twist at the step's end."""
    n = min(len(o), len(w))
    o, w = o[:n], np.nan_to_num(w[:n])
    pos, vel, omg = o[:, 3:6], o[:, 10:13], o[:, 13:16]
    F, T, r = w[:, :3], w[:, 3:6], w[:, 6:9]
    v_r = vel + np.cross(omg, r - pos)
    return float(np.sum(np.sum(F * v_r, axis=1) + np.sum(T * omg, axis=1)) * dt)


args = sys.argv[1:]
wrench = None
if "--wrench" in args:
    i = args.index("--wrench")
    wrench = np.fromfile(args[i + 1], dtype="<f8").reshape(-1, 9)
    del args[i:i + 2]
if len(args) < 2:
    sys.exit(__doc__)
ref = load(args[0])
c = {n: i for i, n in enumerate(COLS)}
soil = np.ones(len(ref), bool)
if wrench is not None:
    f = np.linalg.norm(np.nan_to_num(wrench[:len(ref), :3]), axis=1)
    soil = f > 100
print(f"reference {args[0]}: {len(ref)} steps" +
      (f"; {int(soil.sum())} with a soil force above 100 N" if wrench is not None else "; no wrench given"))
scale = {k: np.max(np.abs(ref[:, c[k]])) for k in ("a_long", "a_vert", "j_long", "j_vert", "lift_force", "tilt_force")}
print("force scales (max |ref|): " + ", ".join(f"{k} {v / 1e3:.0f} kN" for k, v in scale.items()))
print("| run | bucket position max / rms [mm] | bucket angle max [mrad] | bucket velocity max [mm/s] | "
      "A-pin force max / rms [% of max] | J-pin force max [%] | lift / tilt force max [%] | edge max [mm] | soil work [J] (change) |")
print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
w_ref = soil_work(ref, wrench, 1e-3) if wrench is not None else None
if w_ref is not None:
    print(f"| {args[0]} (reference) | | | | | | | | {w_ref:.6g} |")
for path in args[1:]:
    o = load(path)
    n = min(len(o), len(ref))
    r, o = ref[:n], o[:n]
    dp = np.linalg.norm(o[:, c["bucket0"]:c["bucket0"] + 3] - r[:, c["bucket0"]:c["bucket0"] + 3], axis=1)
    da = quat_angle(o[:, c["bucket3"]:c["bucket3"] + 4], r[:, c["bucket3"]:c["bucket3"] + 4])
    dv = np.linalg.norm(o[:, c["bucket7"]:c["bucket7"] + 3] - r[:, c["bucket7"]:c["bucket7"] + 3], axis=1)
    dA = np.hypot(o[:, c["a_long"]] - r[:, c["a_long"]], o[:, c["a_vert"]] - r[:, c["a_vert"]]) / max(scale["a_long"], scale["a_vert"])
    dJ = np.hypot(o[:, c["j_long"]] - r[:, c["j_long"]], o[:, c["j_vert"]] - r[:, c["j_vert"]]) / max(scale["j_long"], scale["j_vert"])
    dl = np.abs(o[:, c["lift_force"]] - r[:, c["lift_force"]]) / scale["lift_force"]
    dt = np.abs(o[:, c["tilt_force"]] - r[:, c["tilt_force"]]) / scale["tilt_force"]
    de = np.hypot(o[:, c["edge_x"]] - r[:, c["edge_x"]], o[:, c["edge_z"]] - r[:, c["edge_z"]])
    print(f"| {path} | {1e3 * dp.max():.3g} / {1e3 * np.sqrt(np.mean(dp ** 2)):.3g} | {1e3 * da.max():.3g} | "
          f"{1e3 * dv.max():.3g} | {100 * dA.max():.3g} / {100 * np.sqrt(np.mean(dA ** 2)):.3g} | {100 * dJ.max():.3g} | "
          f"{100 * dl.max():.3g} / {100 * dt.max():.3g} | {1e3 * de.max():.3g} | " +
          (f"{soil_work(o, wrench, 1e-3):.6g} ({soil_work(o, wrench, 1e-3) / w_ref - 1:+.2e}) |" if w_ref is not None else "- |"))
