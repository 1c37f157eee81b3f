"""Summarises the timing datasets of a cosim_master HDF5 file (docs/output.md)."""
import sys

import h5py
import numpy as np

with h5py.File(sys.argv[1], "r") as f:
    wall = f["timing/step_wall"][1:]
    print(f"macro steps: {wall.size}, wall per step: median {np.median(wall)*1e6:.1f} us")
    total_bus = 0.0
    for p in f["participants"]:
        rt = f[f"participants/{p}/timing/round_trip"][1:]
        cp = f[f"participants/{p}/timing/compute"][1:]
        bus = rt - cp
        total_bus = max(total_bus, bus.sum())
        print(f"{p:>12}: round trip median {np.median(rt)*1e6:7.1f} us  p99 {np.percentile(rt, 99)*1e6:7.1f} us | "
              f"bus part median {np.median(bus)*1e6:7.1f} us  p99 {np.percentile(bus, 99)*1e6:7.1f} us | "
              f"compute median {np.median(cp)*1e6:6.1f} us")
    print(f"bus share of wall time (slowest participant, Jacobi steps overlap): {100*total_bus/wall.sum():.1f} %")
    print("anchor (facts.md): a 100-byte LCM request/reply on loopback takes a median of about 45-80 us")
