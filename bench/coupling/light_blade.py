#!/usr/bin/python3
"""A DEM scene where explicit coupling fails and implicit coupling holds (docs/coupling.md,
"A light blade").

    /usr/bin/python3 bench/coupling/light_blade.py [--out DIR] [--quick]

Runs configs/blade_light.yaml (a 5 kg blade on a 1e5 N/m spring to its driver, pushed through
500 spheres of the paper's soil, DEM step 1e-4 s) as three processes over LCM:

* explicit Jacobi at 0.1 ms (the DEM step: the reference and the cost anchor), 0.2, 0.5 and 1 ms
  (the paper's macro step);
* implicit Jacobi at 1 ms with IQN-ILS (reuse 8) and with Aitken, IQN-ILS at 2 ms, each stopping
  at 30 iterations, and Aitken at 1 ms and IQN-ILS at 2 and 5 ms accepting a step at 30 iterations
  (`at max`: how many);
* the reference again with particle snapshots, to count the grains on the plate
  (--quick: explicit 0.1 and 1 ms, IQN-ILS 1 ms and the snapshots).

For each: how it ended (finished, or the message that stopped it), the coupling energy
residual, the mean draft force over the push (1.3-2.0 s) against the reference, the rms change of
the force from one macro step to the next (chatter), iterations per step in the bed (1.2-2.0 s),
the soil's compute seconds and the CPU seconds of the run (master and participants, from the
kernel's accounting) over the reference's.

Beside them, cosim_stability's limits for the blade against a bed of n contacts, each the wall
law's stiffness k = 4e7 Pa x r and its damping from the restitution 0.3, behind the contacts the
grains' mass (n x 3.39 kg) held by the same stiffness; n is counted in the reference run's
particle snapshots (grains overlapping the plate). "soil/ref": the soil's compute seconds over the
reference's; "CPU/ref": the run's CPU seconds (master and participants) over the reference's.
"""
import argparse
import csv
import os
import resource
import subprocess
import sys
import tempfile

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIG = os.path.join(ROOT, "configs/blade_light.yaml")
MAX_IT = 30
IQN = ["coupling.type=implicit", f"coupling.max_iterations={MAX_IT}", "coupling.at_max_iterations=stop",
       "coupling.convergence=[{connection: tool.blade_wrench, measure: absolute_or_relative, absolute: 10.0, relative: 1.0e-3}]",
       "coupling.acceleration={type: iqn_ils, relaxation: 0.5, reuse: 8}"]
# Accept a step at max_iterations (with a warning) instead of stopping: the run goes on.
ACCEPT = ["coupling.at_max_iterations=accept"]
AITKEN = IQN[:4] + ["coupling.acceleration={type: aitken, relaxation: 0.5}"]

# The paper's soil at the wall (configs/blade_bed.yaml): k = 4e7 Pa x r_i, restitution 0.3,
# grains of radius 60-75 mm (uniform) and density 2600.
R_MEAN = 0.0675
K_WALL = 4.0e7 * R_MEAN
GRAIN_MASS = 2600 * 4 / 3 * np.pi * ((0.075 ** 4 - 0.06 ** 4) / 4 / 0.015)
ZETA = -np.log(0.3) / np.sqrt(np.pi ** 2 + np.log(0.3) ** 2)
ETA_WALL = 2 * ZETA * np.sqrt(K_WALL * GRAIN_MASS)


def run(name, H, sets, out, port):
    h5 = os.path.join(out, name + ".h5")
    soil = os.path.join(out, name + "_soil.h5")
    extra = []
    if name == "snapshots_0.1ms":  # the reference again, with particle snapshots to count contacts
        extra = ["--set", "participants.soil.parameters={output.file: '%s', output.particles_every: 0.05}" % soil]
    cmd = ["nice", os.path.join(ROOT, "build/bin/cosim_master"), CONFIG, "--output", h5,
           "--set", "output.progress=off", "--set", f"bus.url=udpm://239.255.76.67:{port}?ttl=0",
           "--set", f"time.macro_step={H}"] + extra + sum((["--set", s] for s in sets), [])
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, cwd=out, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    log = p.stdout + p.stderr
    failed = [line for line in log.splitlines() if "run failed" in line]
    r = {"name": name, "H": H, "exit": p.returncode, "cpu": cpu,
         "ended": failed[0].split("run failed: ", 1)[1] if failed else "finished"}
    if os.path.exists(h5):
        with h5py.File(h5) as f:
            if "status" in f:
                status = f["status"][()]
                status = status.decode() if isinstance(status, bytes) else str(status)
                r["ended"] = "finished" if status == "finished" else status.replace("stopped: ", "", 1)
    if not os.path.exists(h5):
        r.update(t_end=0.0, energy=np.nan, fx=np.nan, chatter=np.nan, iterations=np.nan, max_iterations=0,
                 soil_compute=np.nan, max_force=np.nan, at_max=0, wall=np.nan)
        return r, log
    with h5py.File(h5) as f:
        t = f["time"][:].ravel()
        fx = f["connections/tool.blade_wrench/received"][:, 0]
        force = np.linalg.norm(f["connections/tool.blade_wrench/received"][:, :3], axis=1)
        it = f["timing/iterations"][:].ravel()
        energy = f["power/blade/energy_residual"][:].ravel()
        compute = f["participants/soil/timing/compute"][1:].sum()
        wall = f["timing/step_wall"][1:].sum()
    push = (t > 1.3) & (t <= 2.0)
    bed = (t > 1.2) & (t <= 2.0)
    r.update(t_end=float(t[-1]), energy=float(energy[-1]), fx=float(fx[push].mean()) if push.any() else np.nan,
             chatter=float(np.sqrt(np.mean(np.diff(fx[push]) ** 2))) if push.sum() > 1 else np.nan,
             iterations=float(it[bed].mean()) if bed.any() else np.nan,
             max_iterations=int(it.max()), soil_compute=float(compute), max_force=float(force.max()),
             at_max=int((it >= MAX_IT).sum()) if "coupling.type=implicit" in sets else 0, wall=float(wall))
    if name == "snapshots_0.1ms":
        r["contacts"] = count_contacts(soil, f_master=h5)
    return r, log


def count_contacts(soil_h5, f_master):
    """Grains overlapping the plate (x = blade x, |y - y_b| <= 0.3, 0 <= z - z_b <= 0.4) in the
    snapshots of the push (1.3-2.0 s): mean and range."""
    counts = []
    with h5py.File(f_master) as m:
        t = m["time"][:].ravel()
        pose = m["connections/soil.blade/received"][:, :3]
    with h5py.File(soil_h5) as f:
        for key in f["particles"]:
            g = f["particles"][key]
            ts = float(g.attrs["time"])
            if not (1.3 <= ts <= 2.0):
                continue
            b = pose[np.argmin(np.abs(t - ts))]
            x, rad = g["position"][:], g["radius"][:]
            near = (np.abs(x[:, 0] - b[0]) < rad) & (np.abs(x[:, 1] - b[1]) <= 0.3 + rad) & \
                   (x[:, 2] >= b[2] - rad) & (x[:, 2] <= b[2] + 0.4 + rad)
            counts.append(int(near.sum()))
    return counts


def stability(n):
    """cosim_stability's explicit Jacobi (1,0) and implicit limits for the blade against n contacts."""
    cc, dc, m2 = n * K_WALL, n * ETA_WALL, n * GRAIN_MASS
    cmd = [os.path.join(ROOT, "build/bin/cosim_stability"), "--scheme", "jacobi", "--kq", "1", "--kf", "0",
           "--implicit", "--csv", "/dev/stdout"] + sum((["--param", f"{k}={v}"] for k, v in
           [("m1", 5.0), ("c1", 1e5), ("d1", 300.0), ("m2", m2), ("c2", cc), ("d2", dc), ("cc", cc), ("dc", dc)]), [])
    p = subprocess.run(cmd, capture_output=True, text=True)
    lines = [line for line in p.stdout.splitlines() if line.startswith(("scheme,", "jacobi,"))]
    rows = list(csv.DictReader(lines))
    return rows[0] if rows else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", help="keep the records in this folder (default: a temporary one)")
    ap.add_argument("--quick", action="store_true", help="explicit 0.1 and 1 ms, IQN-ILS at 1 ms only")
    a = ap.parse_args()
    for b in ("cosim_master", "dem_service", "prescribed_adapter", "cosim_stability"):
        if not os.path.exists(os.path.join(ROOT, "build/bin", b)):
            sys.exit(f"light_blade: build/bin/{b} is missing: build first (docs: README.md)")
    runs = [("explicit_0.1ms", 1e-4, []), ("explicit_0.2ms", 2e-4, []), ("explicit_0.5ms", 5e-4, []),
            ("explicit_1ms", 1e-3, []), ("iqn_ils_1ms", 1e-3, IQN), ("aitken_1ms", 1e-3, AITKEN),
            ("aitken_1ms_accept", 1e-3, AITKEN + ACCEPT), ("iqn_ils_2ms", 2e-3, IQN),
            ("iqn_ils_2ms_accept", 2e-3, IQN + ACCEPT), ("iqn_ils_5ms_accept", 5e-3, IQN + ACCEPT),
            ("snapshots_0.1ms", 1e-4, [])]
    if a.quick:
        runs = [r for r in runs if r[0] in ("explicit_0.1ms", "explicit_1ms", "iqn_ils_1ms", "snapshots_0.1ms")]
    out = a.out or tempfile.mkdtemp(prefix="light_blade_")
    os.makedirs(out, exist_ok=True)
    results = []
    for i, (name, H, sets) in enumerate(runs):
        r, log = run(name, H, sets, out, 7960 + i)
        if r["exit"] not in (0, 1):
            sys.exit(f"light_blade: {name} was refused (exit {r['exit']}):\n{log[-2000:]}")
        results.append(r)
        print(f"  {name}: {r['ended'][:100]}", flush=True)
    ref = results[0]
    print(f"\nlight blade (configs/blade_light.yaml): 5 kg on 1e5 N/m through 500 spheres of the paper's soil, "
          f"DEM step 1e-4 s; reference = explicit at 0.1 ms")
    print(f"{'run':19} {'H [ms]':>6} {'ended':>9} {'E_res [J]':>11} {'Fx 1.3-2 s [N]':>15} {'vs ref':>8} "
          f"{'chatter [N]':>11} {'max|F| [N]':>10} {'iter/step':>9} {'max it':>6} {'at max':>6} {'soil [s]':>8} "
          f"{'soil/ref':>8} {'CPU/ref':>7}")
    for r in results:
        if r["name"] == "snapshots_0.1ms":
            continue
        ended = "finished" if r["ended"] == "finished" else f"t={r['t_end']:.3f}"
        rel = (r["fx"] / ref["fx"] - 1) * 100 if np.isfinite(r["fx"]) else np.nan
        print(f"{r['name']:19} {r['H'] * 1e3:6.1f} {ended:>9} {r['energy']:11.4g} {r['fx']:15.1f} {rel:+7.2f}% "
              f"{r['chatter']:11.1f} {r['max_force']:10.3g} {r['iterations']:9.2f} {r['max_iterations']:6d} "
              f"{r['at_max']:6d} {r['soil_compute']:8.2f} {r['soil_compute'] / ref['soil_compute']:8.2f} "
              f"{r['cpu'] / ref['cpu']:7.2f}")
    for r in results:
        if r["ended"] != "finished":
            print(f"{r['name']} stopped: {r['ended'][:300]}")
    counts = results[-1].get("contacts", [])
    if counts:
        print(f"\ngrains overlapping the plate in the reference's snapshots (1.3-2.0 s): mean {np.mean(counts):.1f}, "
              f"range {min(counts)}-{max(counts)} ({len(counts)} snapshots)")
    print(f"cosim_stability, Jacobi (1,0), the blade (m1 5 kg, c1 1e5 N/m, d1 300 N s/m) against n contacts "
          f"(cc = n x {K_WALL:.3g} N/m, dc = n x {ETA_WALL:.0f} N s/m, m2 = n x {GRAIN_MASS:.2f} kg, c2 = cc, d2 = dc):")
    print(f"{'n':>3} {'explicit H_crit [ms]':>21} {'implicit converged':>19} {'2 iterations':>13} {'3 iterations':>13}")
    for n in (1, 2, 4, 8, 16):
        c = stability(n)
        if c is None:
            print(f"{n:3d} (cosim_stability gave no row)")
            continue
        def ms(key):
            v = c.get(key, "")
            return f"{float(v) * 1e3:.3f}" if v not in ("", "nan", "none") else "none <= 10 s"
        print(f"{n:3d} {ms('H_crit'):>21} {ms('H_crit_implicit_converged'):>19} {ms('H_crit_implicit_2'):>13} "
              f"{ms('H_crit_implicit_3'):>13}")
    print(f"\nrecords in {out}")


if __name__ == "__main__":
    main()
