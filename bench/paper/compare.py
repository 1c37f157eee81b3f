#!/usr/bin/python3
"""Compare the bucket forces of two paper-scene runs (bench/paper/paper_scene.sh --out A and
--out B, same window and policy): per phase and over the whole maneuver, the relative change of
the force impulse, and the RMS of the force difference, raw and filtered (moving average), over
the RMS of the reference force. Used to judge a change (sleeping, a threshold) against the
scatter of two all-active runs that differ only in summation order (1 against 2 threads).

usage: compare.py REFERENCE_DIR OTHER_DIR [--policy needed] [--filter 0.02]
"""
import argparse
import os
import sys

import h5py
import numpy as np

PHASES = ["penetration", "tilt", "lift"]


def force(folder, policy, k, name):
    path = os.path.join(folder, f"{policy}_{k + 1}_{name}_out.h5")
    if not os.path.exists(path):
        sys.exit(f"compare: {path} is missing; run bench/paper/paper_scene.sh --out {folder} "
                 f"--policies {policy} first")
    with h5py.File(path, "r") as f:
        s = f["tools/bucket/samples"][()]
    if len(s) < 2:
        sys.exit(f"compare: {path} has {len(s)} bucket samples; set output.wrenches_every")
    return s[:, 0], s[:, 1:4]


def smooth(f, dt, window):
    n = max(1, int(round(window / dt)))
    if n == 1:
        return f
    kernel = np.ones(n) / n
    return np.stack([np.convolve(f[:, c], kernel, mode="valid") for c in range(3)], axis=1)


def measures(t_a, f_a, t_b, f_b, window):
    m = min(len(t_a), len(t_b))
    if not np.allclose(t_a[:m], t_b[:m], rtol=0, atol=1e-9):
        sys.exit("compare: the two runs sampled the bucket at different times (window or "
                 "output.wrenches_every differ)")
    t, a, b = t_a[:m], f_a[:m], f_b[:m]
    dt = t[1] - t[0]
    imp_a, imp_b = a.sum(axis=0) * dt, b.sum(axis=0) * dt
    rel_imp = np.linalg.norm(imp_b - imp_a) / max(np.linalg.norm(imp_a), 1e-30)
    rms = lambda x: np.sqrt(np.mean(np.sum(x * x, axis=1)))
    raw = rms(b - a) / max(rms(a), 1e-30)
    fa, fb = smooth(a, dt, window), smooth(b, dt, window)
    filt = rms(fb - fa) / max(rms(fa), 1e-30)
    return rel_imp, raw, filt, np.linalg.norm(imp_a), m


def compare_runs(reference, other, policy, window):
    """Per phase and over the whole maneuver: (name, impulse change, raw, filtered, reference
    impulse, samples), the whole maneuver last."""
    rows, ts, fa_all, fb_all = [], [], [], []
    for k, name in enumerate(PHASES):
        ta, fa = force(reference, policy, k, name)
        tb, fb = force(other, policy, k, name)
        imp, raw, filt, ref, m = measures(ta, fa, tb, fb, window)
        rows.append((name, imp, raw, filt, ref, m))
        ts.append(ta[:m]); fa_all.append(fa[:m]); fb_all.append(fb[:m])
    t = np.concatenate(ts)
    imp, raw, filt, ref, m = measures(t, np.concatenate(fa_all), t, np.concatenate(fb_all), window)
    rows.append(("whole maneuver", imp, raw, filt, ref, m))
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("other")
    p.add_argument("--policy", default="needed")
    p.add_argument("--filter", type=float, default=0.02,
                   help="moving-average window in seconds for the filtered measure (default 0.02)")
    a = p.parse_args()
    print(f"bucket force of {a.other} against {a.reference} ({a.policy}; filter {a.filter} s)")
    print("| phase | samples | impulse of the reference [N s] | impulse change | force change raw "
          "| force change filtered |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for name, imp, raw, filt, ref, m in compare_runs(a.reference, a.other, a.policy, a.filter):
        print(f"| {name} | {m} | {ref:.4g} | {100 * imp:.2f} % | {100 * raw:.2f} % | "
              f"{100 * filt:.2f} % |")


if __name__ == "__main__":
    main()
