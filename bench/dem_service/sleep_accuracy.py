"""Sleeping particles on the wheel-loader job: speed against accuracy (docs/performance.md,
"Sleeping particles").

Runs the main job (configs/wheel_loader.yaml: Simbody wheel loader + dem_service on the 10k
pile) once all-active (the reference), once all-active with the pile moved by 10 nm (seeded,
particles.perturb: the scene's run-to-run scatter, as the ensembles of
docs/wheel_loader_studies.md draw it; a thread count no longer changes a bit), and once per
sleep threshold. Prints per run: the DEM's compute time (sum of the soil participant's per-step
compute), its speed-up against the reference, the mean share of particles asleep, and the change
of the bearing forces against the reference (charts.py's measure: RMS difference of the four
section forces, raw and 0.25 s filtered, relative to the reference's RMS; plus the A-bearing
longitudinal force's mean over the filling phase 2 s .. end). Draws speed-up against filtered
error.

  /usr/bin/python3 bench/dem_service/sleep_accuracy.py [--end 3] [--out results/sleep_study]
      [--thresholds SPEED/STEPS/TOOL[/WAKE],...] [--only NAME,...] [--table-only]

A threshold is scene.sleep.speed (m/s) / steps / tool_distance (m) [/ wake_speed (m/s)]; the
default list is 0.005/500/1.0,0.02/500/0.5,0.05/200/0.25. All runs start at once, each under
nice -n 19 on its own private LCM URL, the DEM on 1 thread. The speed-up is of the soil
process's CPU seconds (/usr/bin/time), which a shared machine inflates less than wall time; the
table gives the DEM's wall time too.
"""
import argparse
import json
import os
import subprocess
import sys
import time

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "master", "studies"))
import charts  # noqa: E402

SIGNALS = [{"path": f"participants/loader/outputs/{s}"} for s in ("a_long", "j_long", "a_vert", "j_vert")]
SOIL = "participants.soil.parameters"


def sleep_set(speed, steps, tool_distance, wake=None):
    sets = {f"{SOIL}.scene.sleep.enabled": "true", f"{SOIL}.scene.sleep.speed": str(speed),
            f"{SOIL}.scene.sleep.steps": str(steps), f"{SOIL}.scene.sleep.tool_distance": str(tool_distance)}
    if wake is not None:
        sets[f"{SOIL}.scene.sleep.wake_speed"] = str(wake)
    return sets


DEFAULT_THRESHOLDS = "0.005/500/1.0,0.02/500/0.5,0.05/200/0.25"
BASE_RUNS = [
    ("active", "all active (reference)", {}),
    ("active_moved", "all active, pile moved by 10 nm (scatter)",
     {f"{SOIL}.particles.perturb.amplitude": "1.0e-8", f"{SOIL}.particles.perturb.seed": "1"}),
]


def threshold_runs(text):
    """The sleep runs of --thresholds: SPEED/STEPS/TOOL[/WAKE], comma-separated."""
    runs = []
    for item in filter(None, text.split(",")):
        parts = item.split("/")
        try:
            if len(parts) not in (3, 4):
                raise ValueError
            speed, tool = float(parts[0]), float(parts[2])
            steps = int(parts[1])
            wake = float(parts[3]) if len(parts) == 4 else None
        except ValueError:
            sys.exit(f"sleep_accuracy: threshold '{item}' is not SPEED/STEPS/TOOL[/WAKE] "
                     f"(e.g. 0.02/500/0.5 or 0.05/200/0.25/0.01)")
        if not (speed > 0 and steps > 0 and tool >= 0 and (wake is None or 0 < wake <= speed)):
            sys.exit(f"sleep_accuracy: threshold '{item}': need speed > 0, steps > 0, tool "
                     f"distance >= 0 and 0 < wake <= speed")
        label = f"sleep: speed {parts[0]} m/s, {steps} steps, tool {parts[2]} m"
        if wake is not None:
            label += f", wake {parts[3]} m/s"
        runs.append(("sleep_" + item.replace("/", "_"), label, sleep_set(speed, steps, tool, wake)))
    if not runs:
        sys.exit("sleep_accuracy: --thresholds is empty")
    return runs


def start(k, name, sets, args):
    """Starts one run; the soil participant runs under /usr/bin/time so its CPU seconds (not
    only its wall time, which a shared machine inflates) are known."""
    h5 = os.path.join(args.out, name + ".h5")
    log = os.path.join(args.out, name + ".log")
    cpu = os.path.join(args.out, name + ".cpu")
    bus = args.bus.replace("PORT", str(7743 + k))
    launch = json.dumps(["/usr/bin/time", "-o", cpu, "-f", "%U %S %e",
                         os.path.join(ROOT, "build/bin/dem_service"), "${config_dir}/soil/pile.yaml"])
    cmd = ["nice", "-n", "19", os.path.join(ROOT, "build/bin/cosim_master"),
           os.path.join(ROOT, "configs/wheel_loader.yaml"), "--output", h5,
           "--set", "output.csv=", "--set", "output.progress=off",
           "--set", f"time.end={args.end}", "--set", f"bus.url={bus}",
           "--set", f"participants.soil.launch={launch}",
           "--set", f"{SOIL}.output.file=\"\"", "--set", f"{SOIL}.scene.threads=1"]
    for key, v in sets.items():
        cmd += ["--set", f"{key}={v}"]
    f = open(log, "w")
    f.write(" ".join(cmd) + "\n")
    f.flush()
    # Passive OpenMP waits: a 2-thread DEM at nice 19 on a loaded machine would spin otherwise.
    env = dict(os.environ, OMP_WAIT_POLICY="PASSIVE")
    return name, log, subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT, env=env)


def load(name, args):
    h5 = os.path.join(args.out, name + ".h5")
    with h5py.File(h5, "r") as f:
        t = f["time"][:]
        out = {s["path"]: np.asarray(f[s["path"]][:], dtype=float).reshape(len(t), -1)[:, 0] for s in SIGNALS}
        dem = float(np.sum(f["participants/soil/timing/compute"][:]))
        d = "participants/soil/diagnostics/sleeping"
        asleep = float(np.nanmean(f[d][:])) if d in f else 0.0
        wall = float(np.sum(f["timing/step_wall"][:]))
    try:  # a run stopped early (--partial) has no CPU seconds: the compute wall time stands in
        user, system, _ = (float(x) for x in open(os.path.join(args.out, name + ".cpu")).read().split()[-3:])
        cpu = user + system
    except (OSError, ValueError):
        cpu = None
    return {"t": t, "y": out, "dem": dem, "asleep": asleep, "wall": wall, "cpu": cpu,
            "compute": np.asarray(f_compute(h5))}


def f_compute(h5):
    with h5py.File(h5, "r") as f:
        return f["participants/soil/timing/compute"][:]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--end", type=float, default=3.0, help="simulated seconds of the maneuver")
    ap.add_argument("--out", default="results/sleep_study")
    ap.add_argument("--bus", default="udpm://239.255.76.143:PORT?ttl=0", help="PORT: 7743 + run index")
    ap.add_argument("--only", default="", help="comma-separated run names to (re)run")
    ap.add_argument("--table-only", action="store_true", help="only read existing runs")
    ap.add_argument("--particles", type=float, default=10000)
    ap.add_argument("--thresholds", default=DEFAULT_THRESHOLDS,
                    help="SPEED/STEPS/TOOL[/WAKE],... (m/s, steps, m, m/s)")
    args = ap.parse_args()
    if not args.end > 0:
        sys.exit(f"sleep_accuracy: --end must be > 0 s, got {args.end}")
    RUNS = BASE_RUNS + threshold_runs(args.thresholds)
    args.out = os.path.join(ROOT, args.out) if not os.path.isabs(args.out) else args.out
    os.makedirs(args.out, exist_ok=True)
    only = set(filter(None, args.only.split(",")))
    if not args.table_only:
        pile = os.path.join(ROOT, "results/pile_small.h5")
        if not os.path.exists(pile):  # as scripts/run.sh: the main job's pile, prepared once
            print("sleep_accuracy: preparing the soil pile (once): dem_run configs/soil/pile_prepare.yaml",
                  flush=True)
            if subprocess.call([os.path.join(ROOT, "build/bin/dem_run"), "configs/soil/pile_prepare.yaml"],
                               cwd=ROOT) != 0:
                sys.exit("sleep_accuracy: preparing results/pile_small.h5 failed (see above); "
                         "build first with bash scripts/build.sh")
        subprocess.call(["bash", os.path.join(ROOT, "scripts/multicast.sh")])
        t0 = time.monotonic()
        procs = [start(k, name, sets, args) for k, (name, _, sets) in enumerate(RUNS)
                 if not only or name in only]
        if not procs:
            sys.exit(f"sleep_accuracy: --only {args.only} names no run; the runs are "
                     + ", ".join(name for name, _, _ in RUNS))
        for name, log, p in procs:  # concurrently: all at nice 19, each a private bus URL
            code = p.wait()
            print(f"  {name}: exit {code} after {time.monotonic() - t0:.0f} s", flush=True)
            if code != 0:
                sys.exit(f"sleep_accuracy: {name} failed, see {log}")
    res = {}
    for name, label, _ in RUNS:
        if os.path.exists(os.path.join(args.out, name + ".h5")):
            res[name] = load(name, args)
    if "active" not in res:
        sys.exit(f"sleep_accuracy: no reference run in {args.out} (active.h5); run without "
                 f"--table-only first")
    # Runs stopped early: compare over the time all of them reached.
    t_end = min(r["t"][-1] for r in res.values())
    n_min = min(len(r["t"]) for r in res.values())
    for r in res.values():
        keep = r["t"] <= t_end
        r["t"] = r["t"][keep]
        r["y"] = {k: v[keep] for k, v in r["y"].items()}
        r["dem"] = float(np.sum(r["compute"][:n_min]))
    partial = any(r["cpu"] is None for r in res.values())
    if partial:
        print(f"partial runs: compared up to t = {t_end:.3f} s; speed-up from the DEM compute wall time")
    ref = res["active"]
    fill = ref["t"] >= 2.0
    a_ref = np.mean(ref["y"][SIGNALS[0]["path"]][fill])
    print(f"\nwheel-loader job, {args.end:g} s of maneuver; reference: all active, DEM on 1 thread; "
          f"A-bearing longitudinal mean over 2 s .. end: {a_ref/1e3:.1f} kN\n")
    print("| run | DEM CPU [s] | speed-up (CPU) | DEM compute wall [s] | asleep (mean) | force change raw | filtered | A_long mean 2 s..end |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    points = []
    for name, label, _ in RUNS:
        if name not in res:
            continue
        r = res[name]
        raw, filt = charts.errors((ref["t"], ref["y"], 0), (r["t"], r["y"], 0), SIGNALS, 0.25)
        a = np.mean(r["y"][SIGNALS[0]["path"]][r["t"] >= 2.0])
        speed = ref["dem"] / r["dem"] if partial else ref["cpu"] / r["cpu"]
        err = "" if name == "active" else f"{100*raw:.1f} %"
        errf = "" if name == "active" else f"{100*filt:.1f} %"
        cpu = "" if r["cpu"] is None else f"{r['cpu']:.0f}"
        print(f"| {label} | {cpu} | {speed:.2f} | {r['dem']:.0f} | {100*r['asleep']/args.particles:.0f} % | "
              f"{err} | {errf} | {a/1e3:.1f} kN ({100*(a/a_ref-1):+.1f} %) |")
        if name != "active":
            points.append((name, label, speed, filt))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        for name, label, speed, filt in points:
            ax.plot(100 * filt, speed, "o" if name.startswith("sleep") else "s",
                    color="C0" if name.startswith("sleep") else "C3")
            ax.annotate(label.replace("sleep: ", ""), (100 * filt, speed), fontsize=7,
                        xytext=(4, 4), textcoords="offset points")
        scatter = [100 * f for n, _, _, f in points if n == "active_moved"]
        if scatter:
            ax.axvline(scatter[0], color="C3", ls="--", lw=0.8, label="run-to-run scatter (pile moved by 10 nm)")
            ax.legend(fontsize=7, loc="lower right")
        ax.set_xlabel("bearing-force change vs all-active run, filtered [%]")
        ax.set_ylabel("DEM speed-up (CPU seconds) vs all-active run")
        ax.set_title(f"Sleeping particles, wheel-loader job ({args.end:g} s)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.margins(x=0.45, y=0.1)
        fig.tight_layout()
        png = os.path.join(args.out, "speed_accuracy.png")
        fig.savefig(png, dpi=120)
        print(f"\nchart: {os.path.relpath(png, ROOT)}")
    except ImportError:
        pass


if __name__ == "__main__":
    main()
