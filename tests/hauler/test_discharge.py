"""The hauler's discharge over LCM on loopback (issue 12; docs/hauler.md), a small load:

* the load is prepared with the project's own config (dem_run
  configs/soil/hauler_load_lattice_prepare.yaml: 2,907 coarse grains, r 8-10 cm, 23.3 t, at the
  pose the hauler starts in under it; docs/hauler.md) and the co-simulation is started from
  configs/hauler_lattice.yaml alone (the first 10.5 s of its tipping profile: the soil flows from
  about 7.5 s). The coarse lattice load of before issue 43 keeps the test at about 2 minutes;
  the hauler job's dry-sand load (configs/hauler.yaml) has 2.3x the grains at half the step
  (cosim_master launches hauler_adapter and the same dem_service as the wheel loader's);
* the soil is conserved: grains in the scene + grains removed = the grains at the start, at
  every step, exactly;
* as the body tips, before the soil flows, the front axle's vertical tire force falls and the
  rear axles' rises (the load's centre of gravity moves back towards the hinge);
* the longitudinal tire forces are near zero before tipping and clearly not while the soil
  flows out: the soil pushes the body forward as it leaves (its F_x on the body > 0), so the
  braked tires pull the machine back (their summed F_x < 0);
* a second run is bit-identical.
"""
import os
import re
import subprocess
import sys
import tempfile
import unittest

import h5py
import numpy as np

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)
PORT = 7500 + os.getpid() % 400


def body_frame(x, pose):
    """Particle centres (n x 3, ground) in the body frame of pose (position, quaternion w x y z)."""
    h = np.asarray(pose[:3])
    w, a, b, c = pose[3:7]
    R = np.array([[1 - 2 * (b * b + c * c), 2 * (a * b - c * w), 2 * (a * c + b * w)],
                  [2 * (a * b + c * w), 1 - 2 * (a * a + c * c), 2 * (b * c - a * w)],
                  [2 * (a * c - b * w), 2 * (b * c + a * w), 1 - 2 * (a * a + b * b)]])
    return (x - h) @ R


class Discharge(unittest.TestCase):
    def test_small_discharge(self):
        with tempfile.TemporaryDirectory() as tmp:
            load = os.path.join(tmp, "load.h5")
            prep = subprocess.run(
                [os.path.join(BIN, "dem_run"), f"{ROOT}/configs/soil/hauler_load_lattice_prepare.yaml",
                 "--set", f"settle.checkpoint={load}", "--set", f"output.file={tmp}/prep.h5"],
                capture_output=True, text=True, cwd=ROOT)
            self.assertEqual(prep.returncode, 0, prep.stdout + prep.stderr)
            # The static load the machine starts under: the settled load's mass, centre of
            # gravity and radius of gyration in the body frame at the preparation's pose.
            text = open(f"{ROOT}/configs/soil/hauler_load_lattice_prepare.yaml").read()
            m = re.search(r"position: \[([-\d.e]+), 0, ([-\d.e]+)\], orientation: \[([-\d.e]+), 0, ([-\d.e]+), 0\]", text)
            pose = [float(m.group(1)), 0.0, float(m.group(2)), float(m.group(3)), 0.0, float(m.group(4)), 0.0]
            with h5py.File(load, "r") as f:
                x = f["x"][:].reshape(-1, 3)
                mass = f["mass"][:]
            n0 = len(mass)
            self.assertGreater(n0, 2800)
            local = body_frame(x, pose)
            com = (local * mass[:, None]).sum(0) / mass.sum()
            gyr = np.sqrt(((local[:, 0] - com[0]) ** 2 + (local[:, 2] - com[2]) ** 2) @ mass / mass.sum())
            static = f"{{mass: {mass.sum():.3f}, com: [{com[0]:.4f}, {com[2]:.4f}], gyration_radius: {gyr:.3f}}}"

            # dem_service reads its config file when it starts, before the master's parameters
            # arrive: a copy of configs/soil/hauler_load_lattice.yaml that loads this load (a
            # clean clone has no results/hauler_load_lattice.h5) and the mesh of this build.
            soil_cfg = os.path.join(tmp, "hauler_load.yaml")
            text = open(f"{ROOT}/configs/soil/hauler_load_lattice.yaml").read()
            mesh = os.path.normpath(os.path.join(BIN, "..", "meshes", "hauler_body.stl"))
            self.assertIn("checkpoint: ../../results/hauler_load_lattice.h5", text)
            self.assertIn("mesh: ../../build/meshes/hauler_body.stl", text)
            text = text.replace("checkpoint: ../../results/hauler_load_lattice.h5", f"checkpoint: {load}")
            text = text.replace("mesh: ../../build/meshes/hauler_body.stl", f"mesh: {mesh}")
            with open(soil_cfg, "w") as f:
                f.write(text)

            def run(name, port):
                h5 = os.path.join(tmp, name)
                cmd = [os.path.join(BIN, "cosim_master"), f"{ROOT}/configs/hauler_lattice.yaml", "--output", h5,
                       "--set", "output.csv=", "--set", "output.progress=off", "--set", "time.end=10.5",
                       "--set", f"bus.url=udpm://239.255.76.67:{port}?ttl=0",
                       "--set", f"participants.hauler.parameters.static_load={static}",
                       "--set", f"participants.soil.launch=[dem_service, {soil_cfg}]",
                       # a region of interest that cuts into the pile behind the tail, so grains
                       # are removed within the test's 10.5 s and the balance counts them
                       "--set", "participants.soil.parameters.scene.region={min: [-9.0, -4.0, -1.0], max: [2.0, 4.0, 10.0]}",
                       "--set", "participants.soil.parameters.output.file=\"\""]
                r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                self.assertEqual(r.returncode, 0, r.stdout[-3000:] + r.stderr[-3000:])
                return h5

            a = run("a.h5", PORT)
            with h5py.File(a, "r") as f:
                self.assertEqual(f["status"][()].decode(), "finished")
                t = f["time"][:]
                out = lambda k: f[f"participants/hauler/outputs/{k}"][:].reshape(len(t))  # noqa: E731
                diag = lambda k: f[f"participants/soil/diagnostics/{k}"][:]  # noqa: E731
                soil_fx = f["participants/soil/outputs/body"][:].reshape(len(t), -1)[:, 0]
                front_fz, rear_fz = out("front_fz"), out("rear1_fz") + out("rear2_fz")
                fx = out("front_fx") + out("rear1_fx") + out("rear2_fx")
                angle = np.degrees(out("body_angle"))
                particles, removed, payload = diag("particles"), diag("removed"), diag("payload_body")

            # Soil conserved, exactly in grains (row 0 is the initial output, before any step).
            np.testing.assert_array_equal(particles[1:] + removed[1:], np.full(len(t) - 1, n0))
            self.assertGreater(removed[-1], 100)  # and some of them left the region
            load0 = payload[1]
            self.assertAlmostEqual(load0 / mass.sum(), 1.0, delta=0.02)  # the body holds the load
            self.assertLess(payload[-1], 0.3 * load0)  # and has discharged most of it

            before = (t > 0.5) & (t < 1.0)  # settled after the start, not yet tipping
            flowing = (payload < 0.9 * load0) & (payload > 0.3 * load0) & (t > 1.0)
            self.assertTrue(np.any(flowing), "the soil never flowed out")
            t_flow = t[np.argmax(flowing)]
            # Tipping with the soil still in the body (before it starts to slide out).
            tipped = (t > 1.0) & (t < t_flow) & (angle > 10) & (payload >= 0.99 * load0)
            self.assertTrue(np.any(tipped))
            self.assertLess(front_fz[tipped][-1], front_fz[before].mean() - 1e3)
            self.assertGreater(rear_fz[tipped][-1], rear_fz[before].mean() + 1e3)
            # Longitudinal tire forces: near zero before, not while the soil flows.
            quiet = np.abs(fx[before]).mean()
            busy = np.abs(fx[flowing]).mean()
            print(f"discharge: {n0} grains ({mass.sum() / 1e3:.2f} t), flow from {t_flow:.2f} s at "
                  f"{angle[np.argmax(flowing)]:.1f} deg; front F_z {front_fz[before].mean() / 1e3:.1f} -> "
                  f"{front_fz[tipped][-1] / 1e3:.1f} kN, rear {rear_fz[before].mean() / 1e3:.1f} -> "
                  f"{rear_fz[tipped][-1] / 1e3:.1f} kN; |sum F_x| {quiet:.0f} N before, {busy:.0f} N while flowing")
            self.assertLess(quiet, 500.0)
            self.assertGreater(busy, 4 * quiet)
            self.assertGreater(busy, 500.0)
            # Which way: the soil pushes the body forward, the braked tires pull the machine back.
            self.assertGreater(soil_fx[flowing].mean(), 500.0)
            self.assertLess(fx[flowing].mean(), -500.0)

            # A second run: bit-identical, every output and diagnostic of both participants
            # (the wall-time diagnostics excepted).
            b = run("b.h5", PORT + 1)
            with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
                compared = 0
                for p in ("hauler", "soil"):
                    for group in ("outputs", "diagnostics"):
                        for k in fa[f"participants/{p}/{group}"]:
                            if k.startswith("seconds_"):
                                continue
                            np.testing.assert_array_equal(fa[f"participants/{p}/{group}/{k}"][:],
                                                          fb[f"participants/{p}/{group}/{k}"][:], err_msg=f"{p}/{k}")
                            compared += 1
                self.assertGreater(compared, 20)


if __name__ == "__main__":
    unittest.main()
