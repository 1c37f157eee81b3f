#!/usr/bin/python3
"""Charts of one hauler discharge from its HDF5 file (docs/output.md, docs/hauler.md):

    /usr/bin/python3 master/studies/plot_hauler.py results/hauler.h5 [--participant hauler]
        [--soil soil] [--out results/hauler] [--filter 0.05] [--table 1,6,7,8,9,10,12,16,22]

writes OUT_front_axle.png (longitudinal and vertical tire force at the front axle, TYDEX C, like
the paper's Figure 10), OUT_rear_axles.png (both rear axles on one chart, like Figure 11),
OUT_discharge.png (body angle; the soil the body carries and the grains in its box, the soil
removed; the soil's force on the body; suspension strokes; circuit pressures; hoist force) and
prints the soil mass balance. --table prints docs/hauler.md's results table at the times given
(forces after the moving average, the rest as recorded).
Forces are shown after a centred moving average of --filter seconds (0: raw) over the raw
curve drawn faintly: the DEM's contact noise is in every force. Every force axis says which
way a positive value points: tire forces act on the machine in TYDEX C axes (F_x > 0 pushes it
forward, F_z > 0 carries it), the soil's force on the body is in ground axes (x forward, z up),
the hoist force is positive pushing (raising the body).
"""
import argparse
import os
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ensemble import smooth  # noqa: E402  (the studies' centred moving average)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("h5")
    ap.add_argument("--participant", default="hauler")
    ap.add_argument("--soil", default="soil")
    ap.add_argument("--out", default=None)
    ap.add_argument("--filter", type=float, default=0.05, help="moving average of the forces, s")
    ap.add_argument("--table", default="", help="times [s] for a markdown table of the results, e.g. 1,6,10")
    a = ap.parse_args()
    out = a.out or os.path.splitext(a.h5)[0]
    with h5py.File(a.h5, "r") as f:
        t = f["time"][:]
        base = f"participants/{a.participant}/outputs/"
        if base + "front_fz" not in f:
            raise SystemExit(f"plot_hauler: {a.h5} has no {base}front_fz; is --participant right?")
        g = {k: f[base + k][:].reshape(len(t), -1)[:, 0] for k in
             ("front_fx", "front_fz", "rear1_fx", "rear1_fz", "rear2_fx", "rear2_fz", "front_stroke",
              "rear1_stroke", "rear2_stroke", "front_pressure", "rear_pressure", "hoist_force", "body_angle")}
        d = f"participants/{a.soil}/diagnostics/"
        soil = {k: f[d + k][:] for k in ("payload_body", "particles", "removed", "removed_mass") if d + k in f}
        # the soil's wrench on the body: [fx fy fz tx ty tz rx ry rz], ground axes; row 0 (the
        # service's output before its first step, zero: no contact computed yet) is left out
        w = f"participants/{a.soil}/outputs/body"
        wrench = f[w][:].reshape(len(t), -1) if w in f else None
    tw = t[1:]
    if wrench is not None:
        wrench = wrench[1:]
        status = f["status"][()].decode() if "status" in f else ""

    def forces(ax, keys, title, ylabel):
        for key, label in keys:
            line, = ax.plot(t, g[key] / 1e3, lw=0.4, alpha=0.35)
            ax.plot(t, smooth(t, g[key], a.filter) / 1e3, lw=1.0, color=line.get_color(), label=label)
        ax.set_title(title, fontsize=10)
        ax.set_ylabel(ylabel)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    forces(axes[0], [("front_fx", "front axle")], "Front axle, longitudinal F_x (TYDEX C)",
           "F_x on the machine [kN], + pushes it forward")
    forces(axes[1], [("front_fz", "front axle")], "Front axle, vertical F_z (TYDEX C)",
           "F_z on the machine [kN], + carries it")
    fig.suptitle(f"Tire forces at the front axle during the discharge: {os.path.basename(a.h5)}", fontsize=11)
    fig.tight_layout()
    fig.savefig(out + "_front_axle.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    forces(axes[0], [("rear1_fx", "rear axle 1 (2nd)"), ("rear2_fx", "rear axle 2 (3rd)")],
           "Rear axles, longitudinal F_x (TYDEX C)", "F_x on the machine [kN], + pushes it forward")
    forces(axes[1], [("rear1_fz", "rear axle 1 (2nd)"), ("rear2_fz", "rear axle 2 (3rd)")],
           "Rear axles, vertical F_z (TYDEX C)", "F_z on the machine [kN], + carries it")
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8)
    fig.suptitle(f"Tire forces at both rear axles during the discharge: {os.path.basename(a.h5)}", fontsize=11)
    fig.tight_layout()
    fig.savefig(out + "_rear_axles.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(3, 2, figsize=(11, 10), sharex=True)
    axes[0][0].plot(t, np.degrees(g["body_angle"]), lw=1.0)
    axes[0][0].set_ylabel("body angle [deg], + tipped")
    ax = axes[0][1]
    if wrench is not None:
        # what the body carries: the soil's downward force on it, in tonnes of weight
        carried = -wrench[:, 2] / 9.81 / 1e3
        line, = ax.plot(tw, carried, lw=0.4, alpha=0.35)
        ax.plot(tw, smooth(tw, carried, a.filter), lw=1.0, color=line.get_color(),
                label="carried by the body (soil's downward force / g)")
    if "payload_body" in soil:
        ax.plot(t, soil["payload_body"] / 1e3, lw=1.0, ls="--",
                label="grains inside the body's box (also those\nresting on the pile behind the tail)")
    if "removed_mass" in soil:
        ax.plot(t, soil["removed_mass"] / 1e3, lw=1.0, label="removed (left the region)")
    ax.set_ylabel("soil [t]")
    ax.legend(fontsize=7)
    ax = axes[1][0]
    if wrench is not None:
        for col, label in ((0, "F_x, + forward"), (2, "F_z, + up")):
            line, = ax.plot(tw, wrench[:, col] / 1e3, lw=0.4, alpha=0.35)
            ax.plot(tw, smooth(tw, wrench[:, col], a.filter) / 1e3, lw=1.0, color=line.get_color(), label=label)
        ax.legend(fontsize=8)
    ax.set_ylabel("soil's force on the body [kN]\n(ground axes)")
    ax = axes[1][1]
    for key, label in (("front_stroke", "front"), ("rear1_stroke", "rear 1"), ("rear2_stroke", "rear 2")):
        ax.plot(t, g[key] * 1e3, lw=1.0, label=label)
    ax.set_ylabel("suspension stroke [mm],\n+ extending (0 = compressed)")
    ax.legend(fontsize=8)
    ax = axes[2][0]
    ax.plot(t, g["front_pressure"] / 1e6, lw=1.0, label="front circuit")
    ax.plot(t, g["rear_pressure"] / 1e6, lw=1.0, label="rear circuit (bogie)")
    ax.set_ylabel("pressure [MPa]")
    ax.legend(fontsize=8)
    ax = axes[2][1]
    ax.plot(t, g["hoist_force"] / 1e3, lw=1.0)
    ax.set_ylabel("hoist force [kN],\n+ pushing (raising the body)")
    for row in axes:
        for ax in row:
            ax.grid(alpha=0.3)
    for ax in axes[2]:
        ax.set_xlabel("time [s]")
    fig.suptitle(f"Discharge: body, soil, suspension, hoist ({status})", fontsize=11)
    fig.tight_layout()
    fig.savefig(out + "_discharge.png", dpi=120)
    plt.close(fig)

    if {"particles", "removed"} <= set(soil):
        n0 = soil["particles"][1] + soil["removed"][1]
        bal = soil["particles"] + soil["removed"]
        print(f"plot_hauler: soil count balance: {int(n0)} grains at the start; in the scene + removed "
              f"{'equals it at every step' if np.all(bal[1:] == n0) else 'DIFFERS at some step'}; at the end "
              f"{int(soil['particles'][-1])} in the scene ({soil['payload_body'][-1] / 1e3:.2f} t of them inside the "
              f"body's box), {int(soil['removed'][-1])} removed ({soil['removed_mass'][-1] / 1e3:.2f} t)")
    if wrench is not None:
        print(f"plot_hauler: the body carries {-wrench[-1, 2] / 9.81 / 1e3:.2f} t of soil at the end "
              f"(the soil's downward force on it / g)")
    if a.table:
        table(t, g, soil, wrench, a)
    print(f"plot_hauler: wrote {out}_front_axle.png, {out}_rear_axles.png and {out}_discharge.png")


def table(t, g, soil, wrench, a):
    """docs/hauler.md's results table: one row per requested time (the nearest record row)."""
    f = {k: smooth(t, g[k], a.filter) for k in ("front_fx", "front_fz", "rear1_fx", "rear1_fz", "rear2_fx", "rear2_fz")}
    tw = t[1:]
    carried = smooth(tw, -wrench[:, 2], a.filter) / 9.81 if wrench is not None else None
    push = smooth(tw, wrench[:, 0], a.filter) if wrench is not None else None
    print("| t [s] | body [deg] | carried / in the box [t] | soil F_x on the body [kN] | front F_z [kN] | "
          "rear 1 / rear 2 F_z [kN] | front / rear 1 / rear 2 F_x [kN] | strokes front / rear 1 / rear 2 [mm] | "
          "rear pressure [MPa] | hoist [kN] |")
    print("| --- " * 10 + "|")
    for ts in (float(x) for x in a.table.split(",")):
        i = int(np.argmin(np.abs(t - ts)))
        box = soil["payload_body"][i] / 1e3 if "payload_body" in soil else float("nan")
        c = carried[i - 1] / 1e3 if carried is not None and i > 0 else float("nan")
        px = push[i - 1] / 1e3 if push is not None and i > 0 else float("nan")
        print(f"| {t[i]:g} | {np.degrees(g['body_angle'][i]):.1f} | {c:.2f} / {box:.2f} | {px:.1f} | "
              f"{f['front_fz'][i] / 1e3:.1f} | {f['rear1_fz'][i] / 1e3:.1f} / {f['rear2_fz'][i] / 1e3:.1f} | "
              f"{f['front_fx'][i] / 1e3:.1f} / {f['rear1_fx'][i] / 1e3:.1f} / {f['rear2_fx'][i] / 1e3:.1f} | "
              f"{g['front_stroke'][i] * 1e3:.0f} / {g['rear1_stroke'][i] * 1e3:.0f} / {g['rear2_stroke'][i] * 1e3:.0f} | "
              f"{g['rear_pressure'][i] / 1e6:.2f} | {g['hoist_force'][i] / 1e3:.0f} |")


if __name__ == "__main__":
    main()
