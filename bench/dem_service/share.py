"""Bus + master share of a cosim_master run's step wall time, against the dem participant's compute."""
import sys

import h5py
import numpy as np

with h5py.File(sys.argv[1], "r") as f:
    wall = f["timing/step_wall"][1:]
    dem = f["participants/dem/timing/compute"][1:]
    rt = f["participants/dem/timing/round_trip"][1:]
    master = f["timing/master"][1:]
    n = f["participants/dem/diagnostics/particle_contacts"][1:]
    share = (wall.sum() - dem.sum()) / wall.sum()
    print(f"  {wall.size} macro steps, wall {wall.sum():.2f} s, dem compute {dem.sum():.2f} s "
          f"(median {np.median(dem)*1e3:.1f} ms/step), contacts at the end {n[-1]:.0f}")
    print(f"  bus part of the round trip: median {np.median(rt - dem)*1e6:.0f} us, "
          f"p99 {np.percentile(rt - dem, 99)*1e6:.0f} us; master {master.sum()*1e3:.1f} ms in all")
    print(f"  bus + master share of wall time: {100*share:.2f} %  (goal < 5 %)")
