#!/usr/bin/python3
"""The paper scene's outcomes from one co-simulation record (docs/soil.md, "The paper's scene
before and after"): the outcomes of the main job's ensembles (configs/studies/
wheel_loader_ensemble_dry_sand.yaml), computed the same way (master/studies/ensemble.py: each
series smoothed by a centred 0.25 s moving average, then the statistic):

    /usr/bin/python3 bench/paper/scene_outcomes.py RECORD.h5 [--bulk-density KG_M3] [--label TEXT]

prints the payload at 7 s and at the record's end, the A-bearing longitudinal mean and peak and
the vertical mean over 2-7 s, the time the machine's speed first falls below 0.1 m/s (from 2 s),
and with --bulk-density the fill factor, payload / (4.66 m^3 heaped x bulk density). A record
that ends before 7 s (a run still going or stopped) gives its outcomes up to its end, said so.
Reads a record that is still being written (HDF5 file locking off for this reader).
"""
import argparse
import os
import sys

os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
import h5py  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "master", "studies"))
from ensemble import finite, outcome, smooth  # noqa: E402

HEAPED_M3 = 4.66      # the bucket's heaped volume (docs/wheel_loader.md)
FILTER_S = 0.25       # the ensembles' moving average (filter_seconds)
OUTCOMES = [
    ("A-bearing longitudinal, mean 2-7 s [kN]", "participants/loader/outputs/a_long", {"stat": "mean", "from": 2, "to": 7}, 1e-3),
    ("A-bearing longitudinal, peak 2-7 s [kN]", "participants/loader/outputs/a_long", {"stat": "max", "from": 2, "to": 7}, 1e-3),
    ("A-bearing vertical, mean 2-7 s [kN]", "participants/loader/outputs/a_vert", {"stat": "mean", "from": 2, "to": 7}, 1e-3),
    ("speed first below 0.1 m/s [s]", "participants/loader/outputs/speed", {"stat": "first_below", "threshold": 0.1, "from": 2}, 1.0),
]
PAYLOAD = "participants/soil/diagnostics/payload_bucket"


def series(f, path, n):
    if path not in f:
        raise SystemExit(f"scene_outcomes: the record has no {path}; is it a wheel-loader run with a soil named 'soil'?")
    return f[path][:n].reshape(n, -1)[:, 0].astype(float)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("h5")
    ap.add_argument("--bulk-density", type=float, default=None, help="kg/m^3, for the fill factor")
    ap.add_argument("--label", default=None)
    a = ap.parse_args()
    if a.bulk_density is not None and not (a.bulk_density > 0):
        raise SystemExit(f"scene_outcomes: --bulk-density must be a positive density in kg/m^3, not {a.bulk_density}")
    with h5py.File(a.h5, "r") as f:
        t = f["time"][:].astype(float)
        # a record being written may have some tables a row ahead of others
        n = min([len(t)] + [len(f[p]) for _, p, _, _ in OUTCOMES if p in f] + ([len(f[PAYLOAD])] if PAYLOAD in f else []))
        t = t[:n]
        ys = {p: series(f, p, n) for _, p, _, _ in OUTCOMES}
        payload = series(f, PAYLOAD, n)
    if n < 3:
        raise SystemExit(f"scene_outcomes: {a.h5} holds {n} steps; nothing to measure yet")
    end = t[-1]
    note = ("" if end >= 7 - 1e-9 else f"  (ENDS BEFORE 7 s: the 2-7 s outcomes are over 2-{end:.2f} s)" if end > 2
            else "  (ENDS BEFORE 2 s: no 2-7 s outcome yet)")
    print(f"{a.label or a.h5}: {n} steps, t = {t[0]:.3f}-{end:.3f} s{note}")
    for name, p, o, scale in OUTCOMES:
        tt, yy = finite(t, ys[p])
        v = outcome(tt, smooth(tt, yy, FILTER_S), o) * scale
        print(f"  {name:42s} {v:10.3f}")
    tp, yp = finite(t, payload)
    sp = smooth(tp, yp, FILTER_S)
    i7 = int(np.searchsorted(tp, 7.0 - 1e-9)) if end >= 7 - 1e-9 else len(tp) - 1
    for label, i in ((f"payload at {tp[i7]:.2f} s [t]", i7), (f"payload at the end, {tp[-1]:.2f} s [t]", len(tp) - 1)):
        print(f"  {label:42s} {sp[i] / 1e3:10.3f}   (unsmoothed {yp[i] / 1e3:.3f})")
    if a.bulk_density:
        heaped = HEAPED_M3 * a.bulk_density
        print(f"  heaped bucket at {a.bulk_density:.0f} kg/m^3: {heaped / 1e3:.2f} t; fill factor at "
              f"{tp[i7]:.2f} s {sp[i7] / heaped:.3f}, at the end {sp[-1] / heaped:.3f}")


if __name__ == "__main__":
    main()
