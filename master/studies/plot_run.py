#!/usr/bin/python3
"""Charts of one wheel-loader co-simulation from its HDF5 file (docs/output.md):

    /usr/bin/python3 master/studies/plot_run.py results/wheel_loader.h5 [--participant loader]
        [--soil soil] [--out results/wheel_loader]

writes OUT_bearing_forces.png (A- and J-bearing section forces in the bucket frame,
longitudinal and vertical) and OUT_machine.png (speed, drive force, soil force on the bucket,
cylinder forces).
"""
import argparse
import os

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("h5")
    ap.add_argument("--participant", default="loader")
    ap.add_argument("--soil", default="soil")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    out = a.out or os.path.splitext(a.h5)[0]
    with h5py.File(a.h5, "r") as f:
        t = f["time"][:]
        base = f"participants/{a.participant}/outputs/"
        if base + "a_long" not in f:
            raise SystemExit(f"plot_run: {a.h5} has no {base}a_long; is --participant right?")
        g = {k: f[base + k][:].reshape(len(t), -1)[:, 0] for k in
             ("a_long", "a_vert", "j_long", "j_vert", "speed", "drive_force", "lift_force", "tilt_force")}
        soil = f.get(f"participants/{a.soil}/outputs/bucket")
        soil = soil[:] if soil is not None else None

    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    for ax, key, title in ((axes[0][0], "a_long", "A-bearing, longitudinal"), (axes[0][1], "j_long", "J-bearing, longitudinal"),
                           (axes[1][0], "a_vert", "A-bearing, vertical"), (axes[1][1], "j_vert", "J-bearing, vertical")):
        ax.plot(t, g[key] / 1e3, lw=0.8)
        ax.set_title(title + " (bucket frame)", fontsize=10)
        ax.set_ylabel("kN")
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time [s]")
    fig.suptitle(f"Section forces on the bucket: {os.path.basename(a.h5)}", fontsize=11)
    fig.tight_layout()
    fig.savefig(out + "_bearing_forces.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    axes[0].plot(t, g["speed"], lw=0.9)
    axes[0].set_ylabel("machine speed [m/s]")
    axes[1].plot(t, g["drive_force"] / 1e3, lw=0.9, label="drive force")
    if soil is not None:
        axes[1].plot(t, -soil[:, 0] / 1e3, lw=0.8, label="soil resistance on the bucket (-F_x)")
        axes[1].plot(t, soil[:, 2] / 1e3, lw=0.8, label="soil force on the bucket, vertical (F_z)")
    axes[1].set_ylabel("kN")
    axes[1].legend(fontsize=8)
    axes[2].plot(t, g["lift_force"] / 1e3, lw=0.9, label="lift cylinders")
    axes[2].plot(t, g["tilt_force"] / 1e3, lw=0.9, label="tilt cylinder")
    axes[2].set_ylabel("cylinder force [kN]")
    axes[2].legend(fontsize=8)
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out + "_machine.png", dpi=120)
    plt.close(fig)
    print(f"plot_run: wrote {out}_bearing_forces.png and {out}_machine.png")


if __name__ == "__main__":
    main()
