#!/usr/bin/python3
"""The cost of one rollback of the DEM soil, as a share of its macro step (docs/coupling.md).

    /usr/bin/python3 bench/coupling/rollback_cost.py [--horizon S] [--macro-step H] [--scene main|paper]

Runs the wheel loader (--scene main: configs/wheel_loader.yaml, the 10,000-sphere dry-sand pile
results/pile_dry_sand.h5, prepared by scripts/run.sh; --scene paper: configs/wheel_loader_paper.yaml,
the 150,000-sphere pile results/pile_paper.h5, prepared by bench/paper/prepare_pile.sh) twice over the same horizon at the same macro step: explicit Jacobi
(the anchor) and implicit Jacobi with exactly two iterations per step (min_iterations =
max_iterations = 2, a limit every iteration meets), so that every step is rolled back once. A
rollback is the dem_service's `snapshot` section: the state saved at the step's start and restored
for the second iteration (a participant that can repeat saves at every step, explicit or not, so
the explicit run's section holds the saves alone). Prints, from the runs' own timing tables and records:

* snapshot time per rollback, and per step of the explicit run's soil compute (the goal: under
  15 % of the macro step);
* the implicit run's soil compute per step over the explicit one's (2 when a rollback costs
  nothing: the step is computed twice).
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


SCENES = {"main": ("configs/wheel_loader.yaml", "results/pile_dry_sand.h5", "10,000", "bash scripts/run.sh"),
          "paper": ("configs/wheel_loader_paper.yaml", "results/pile_paper.h5", "150,000",
                    "nice -n 19 bash bench/paper/prepare_pile.sh")}


def run(name, sets, out, binary, config):
    h5 = os.path.join(out, name + ".h5")
    cmd = ["nice", binary, os.path.join(ROOT, config), "--output", h5,
           "--set", "output.csv=", "--set", "output.progress=off",
           "--set", "participants.soil.parameters={output.file: ''}"] + sum((["--set", s] for s in sets), [])
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    log = p.stdout + p.stderr
    if p.returncode != 0:
        sys.exit(f"rollback_cost: {name} failed (exit {p.returncode}):\n{log[-2000:]}")
    # The soil's timing table: 'snapshot | time | %'; and its request count.
    snap = [float(m.group(1)) for m in re.finditer(r"^snapshot\s*\|\s*([0-9.eE+-]+)", log, re.M)]
    requests = [int(m.group(1)) for m in re.finditer(r"dem_service: (\d+) macro steps", log)]
    with h5py.File(h5) as f:
        compute = f["participants/soil/timing/compute"][1:].sum()
        steps = len(f["time"]) - 1
        iterations = f["timing/iterations"][1:].sum()
    return {"snapshot": snap[-1] if snap else float("nan"), "requests": requests[-1] if requests else 0,
            "soil_compute": float(compute), "steps": steps, "iterations": float(iterations)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--horizon", type=float, default=0.05, help="simulated seconds (default 0.05)")
    ap.add_argument("--macro-step", type=float, default=1.0e-3, help="s (default: the main job's 1e-3)")
    ap.add_argument("--scene", choices=sorted(SCENES), default="main",
                    help="main: the 10k main job; paper: the 150k paper-sized pile (default main)")
    a = ap.parse_args()
    if not (a.horizon > 0 and a.macro_step > 0 and a.macro_step <= a.horizon):
        sys.exit(f"rollback_cost: need 0 < --macro-step <= --horizon (got {a.macro_step:g} and {a.horizon:g})")
    config, pile, grains, prepare = SCENES[a.scene]
    if not os.path.exists(os.path.join(ROOT, pile)):
        sys.exit(f"rollback_cost: {pile} is missing: prepare the pile first ({prepare})")
    binary = os.path.join(ROOT, "build/bin/cosim_master")
    common = [f"time.end={a.horizon}", f"time.macro_step={a.macro_step}", "startup_iterations=0"]
    with tempfile.TemporaryDirectory() as out:
        ex = run("explicit", common, out, binary, config)
        im = run("implicit2", common + [
            "coupling.type=implicit", "coupling.min_iterations=2", "coupling.max_iterations=2",
            "coupling.convergence=[{connection: loader.bucket_wrench, measure: absolute, limit: 1.0e30}]"], out, binary, config)
    rollbacks = im["iterations"] - im["steps"]
    per_rollback = im["snapshot"] / max(rollbacks, 1)
    step_compute = ex["soil_compute"] / ex["steps"]
    print(f"wheel loader, {grains} spheres ({a.scene}), macro step {a.macro_step:g} s, {ex['steps']} steps over {a.horizon:g} s")
    print(f"  explicit (anchor): soil compute {step_compute * 1e3:.2f} ms per macro step; snapshots {ex['snapshot']:.4f} s")
    print(f"  implicit, 2 iterations: {rollbacks:.0f} rollbacks, snapshot section {im['snapshot']:.4f} s "
          f"({per_rollback * 1e3:.3f} ms per rollback, save and restore)")
    print(f"  one rollback = {100 * per_rollback / step_compute:.2f} % of the explicit macro step's soil compute (goal < 15 %)")
    print(f"  implicit soil compute per step / explicit = {im['soil_compute'] / im['steps'] / step_compute:.2f} "
          f"(2.00 would be the redo alone)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
