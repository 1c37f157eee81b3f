#!/usr/bin/python3
"""Makes the hauler's load and its start pose agree (docs/hauler.md, "The load").

    /usr/bin/python3 scripts/hauler_load_pose.py [--iterations 2]

The load is settled in the dump body standing at the pose the hauler has at the start of the
discharge, and that pose depends on the load (hauler_adapter's static_load: mass, centre of
gravity, radius of gyration). This script iterates: it asks hauler_adapter for the start pose
under the current static_load (a one-step co-simulation with an empty soil), writes that pose
into configs/soil/hauler_load_prepare.yaml and hauler_load_release.yaml, prepares the load with
dem_run (both stages: results/hauler_load.h5), measures it in the body frame, and repeats. It prints the static_load
to put into configs/hauler.yaml and the remaining change of the pose.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# the load's preparation, in order: deposition with the tail closed, then released
PREPS = [os.path.join(ROOT, "configs/soil/hauler_load_prepare.yaml"),
         os.path.join(ROOT, "configs/soil/hauler_load_release.yaml")]


def rotation(q):
    w, a, b, c = q
    return np.array([[1 - 2 * (b * b + c * c), 2 * (a * b - c * w), 2 * (a * c + b * w)],
                     [2 * (a * b + c * w), 1 - 2 * (a * a + c * c), 2 * (b * c - a * w)],
                     [2 * (a * c - b * w), 2 * (b * c + a * w), 1 - 2 * (a * a + b * b)]])


def start_pose(tmp, static):
    soil = os.path.join(tmp, "soil.yaml")
    with open(soil, "w") as f:
        f.write(f"""scene: {{dt: 2.0e-4, threads: 1}}
materials: {{soil: {{density: 2600}}}}
species: [{{name: grain, material: soil, radius: 0.09}}]
contact: {{particle_particle: {{normal_stiffness: 4.0e7, stiffness_unit: Pa, restitution: 0.3}}}}
tools: [{{name: body, mesh: {ROOT}/build/meshes/hauler_body.stl}}]
particles: {{list: [{{species: grain, position: [50, 0, 5]}}]}}
""")
    h5 = os.path.join(tmp, "probe.h5")
    cmd = [os.path.join(ROOT, "build/bin/cosim_master"), os.path.join(ROOT, "configs/hauler.yaml"),
           "--output", h5, "--set", "output.csv=", "--set", "output.progress=off", "--set", "time.end=0.001",
           "--set", f"participants.soil.launch=[dem_service, {soil}]",
           "--set", f"participants.hauler.parameters.static_load={static}",
           "--set", f"bus.url=udpm://239.255.76.67:{7600 + os.getpid() % 300}?ttl=0"]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp)
    if r.returncode != 0:
        sys.exit("hauler_load_pose: the probe run failed:\n" + r.stdout[-2000:] + r.stderr[-2000:])
    with h5py.File(h5, "r") as f:
        return f["participants/hauler/outputs/body"][0][:7]


def prepare(pose):
    new = (f"- {{time: 0.0, position: [{pose[0]:.6f}, 0, {pose[2]:.6f}], "
           f"orientation: [{pose[3]:.8f}, 0, {pose[5]:.8f}, 0]}}")
    for prep in PREPS:
        text = open(prep).read()
        text, n = re.subn(r"- \{time: 0\.0, position: \[.*?\], orientation: \[.*?\]\}", new, text)
        if n != 1:
            sys.exit(f"hauler_load_pose: {prep} has no single start keyframe to update")
        open(prep, "w").write(text)
    out = os.path.join(ROOT, "results/hauler_load.h5")
    for old in (out, os.path.join(ROOT, "results/hauler_load_bed.h5")):
        if os.path.exists(old):
            os.remove(old)
    for prep in PREPS:
        r = subprocess.run([os.path.join(ROOT, "build/bin/dem_run"), prep], capture_output=True, text=True, cwd=ROOT)
        if r.returncode != 0:
            sys.exit(f"hauler_load_pose: dem_run {prep} failed:\n" + r.stderr[-2000:])
        print("\n".join(line for line in (r.stdout + r.stderr).splitlines()
                        if line.startswith(("Prepared bed:", "settle: at rest", "prepare: deposition"))), flush=True)
    with h5py.File(out, "r") as f:
        x = f["x"][:].reshape(-1, 3)
        m = f["mass"][:]
    local = (x - np.array([pose[0], pose[1], pose[2]])) @ rotation(pose[3:7])
    com = (local * m[:, None]).sum(0) / m.sum()
    gyr = np.sqrt(((local[:, 0] - com[0]) ** 2 + (local[:, 2] - com[2]) ** 2) @ m / m.sum())
    return len(m), m.sum(), (com[0], com[2]), gyr


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iterations", type=int, default=2)
    a = ap.parse_args()
    text = open(os.path.join(ROOT, "configs/hauler.yaml")).read()
    m = re.search(r"static_load: (\{.*\})", text)
    static = m.group(1) if m else "{mass: 23000, com: [2.6, 0.77], gyration_radius: 1.4}"
    with tempfile.TemporaryDirectory() as tmp:
        for it in range(a.iterations):
            pose = start_pose(tmp, static)
            n, mass, com, gyr = prepare(pose)
            static = f"{{mass: {mass:.1f}, com: [{com[0]:.3f}, {com[1]:.3f}], gyration_radius: {gyr:.2f}}}"
            print(f"iteration {it + 1}: start pose {np.round(pose, 6).tolist()}; load {n} grains, static_load {static}")
        check = start_pose(tmp, static)
    print(f"hauler_load_pose: put static_load: {static} into configs/hauler.yaml; the start pose then moves "
          f"by {1e3 * np.linalg.norm(check[:3] - pose[:3]):.2f} mm from the one the load was settled at")


if __name__ == "__main__":
    main()
