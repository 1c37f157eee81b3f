#!/usr/bin/python3
"""The soil's wrench on the bucket from a master record (participants/soil/outputs/bucket, 9 per
row: force, torque about r, r; ground) as raw float64, row k = the wrench the loader holds over
macro step k under Jacobi with an order-0 force predictor; loader_alone --wrench reads it.

    /usr/bin/python3 bench/mbs/export_wrench.py RECORD.h5 OUT.f64
"""
import sys

import h5py
import numpy as np

if len(sys.argv) != 3:
    sys.exit(__doc__)
with h5py.File(sys.argv[1], "r") as f:
    w = np.asarray(f["participants/soil/outputs/bucket"][:], dtype="<f8")
if w.ndim != 2 or w.shape[1] != 9:
    sys.exit(f"export_wrench: {sys.argv[1]}: participants/soil/outputs/bucket is {w.shape}, not (N, 9)")
w.tofile(sys.argv[2])
force = np.linalg.norm(np.nan_to_num(w[:, :3]), axis=1)
print(f"export_wrench: {len(w)} rows to {sys.argv[2]}; |F| > 100 N in {int((force > 100).sum())}, peak {force.max():.0f} N")
