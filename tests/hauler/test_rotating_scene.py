"""The hauler's scene with rotating grains (configs/hauler_rotating.yaml; docs/hauler.md "The load
before and after", docs/soil_models.md), in seconds on a tiny load:

* configs/hauler_rotating.yaml is configs/hauler.yaml with another soil: the same machine, time,
  coupling, predictors and connections; only the soil's launch, the static_load and the output
  files differ; the rotating load's configs are the dry-sand load's with the rotating material
  and their own files (the same body pose, region, walls and preparation);
* stage 1 of the rotating load's preparation (configs/soil/hauler_load_rotating_prepare.yaml)
  with 60 grains instead of 7,000 deposits rotating grains: the resolved config names the
  rotating model with the calibrated material's rolling resistance and friction, and the
  checkpoint carries angular velocities that are not all zero (the grains spun while falling);
* cosim_master runs configs/hauler_rotating.yaml (hauler_adapter + dem_service from
  configs/soil/hauler_load_rotating.yaml, loading that bed) for 50 ms, and the soil's vertical
  force on the body, body lowered and grains at rest, is the grains' weight within 1 %.
The physics of a turned packing is the turning-box test's (dem_Rotation.*).
"""
import os
import subprocess
import sys
import tempfile
import unittest

import h5py
import numpy as np
import yaml

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)
PORT = 7500 + (os.getpid() + 211) % 400


def load(path):
    with open(os.path.join(ROOT, path)) as f:
        return yaml.safe_load(f)


class RotatingScene(unittest.TestCase):
    def test_scene_is_the_dry_sand_scene_with_another_soil(self):
        a, b = load("configs/hauler.yaml"), load("configs/hauler_rotating.yaml")
        self.assertEqual(b["participants"]["soil"]["launch"],
                         ["dem_service", "${config_dir}/soil/hauler_load_rotating.yaml"])
        self.assertEqual(set(b["participants"]["hauler"]["parameters"]), {"static_load"})
        self.assertAlmostEqual(b["participants"]["hauler"]["parameters"]["static_load"]["mass"] / 1e3, 23.5, delta=1.5)
        for key in ("static_load",):
            a["participants"]["hauler"]["parameters"].pop(key)
            b["participants"]["hauler"]["parameters"].pop(key)
        for c in (a, b):
            c["participants"]["soil"].pop("launch")
            c.pop("output")
        self.assertEqual(a, b)
        # the load's configs: the dry sand's with the rotating material and their own files
        for dry, rot in (("hauler_load_prepare", "hauler_load_rotating_prepare"),
                         ("hauler_load_release", "hauler_load_rotating_release"),
                         ("hauler_load", "hauler_load_rotating")):
            d, r = load(f"configs/soil/{dry}.yaml"), load(f"configs/soil/{rot}.yaml")
            self.assertEqual(d["materials"]["soil"]["file"], "../materials/dry_sand.yaml")
            self.assertEqual(r["materials"]["soil"]["file"], "../materials/dry_sand_rotating.yaml")
            for c in (d, r):
                c.pop("materials")
                c.pop("output")
                c["particles"].pop("checkpoint", None)
                c["particles"].pop("model", None)
                for sec in ("prepare", "settle"):
                    c.get(sec, {}).pop("checkpoint", None)
            self.assertEqual(d, r, rot)
        self.assertEqual(load("configs/soil/hauler_load_rotating.yaml")["particles"]["model"], "rotating")

    def test_prepares_and_runs_rotating_grains(self):
        with tempfile.TemporaryDirectory() as tmp:
            tmp = os.environ.get("KEEP_TMP", tmp)
            bed = os.path.join(tmp, "bed.h5")
            prep = subprocess.run(
                [os.path.join(BIN, "dem_run"), f"{ROOT}/configs/soil/hauler_load_rotating_prepare.yaml",
                 "--set", "particles.insert.0.count=60", "--set", "prepare.max_time=2.0", "--set", "prepare.margin=0",
                 "--set", "scene.threads=1", "--set", f"prepare.checkpoint={bed}",
                 "--set", f"output.file={tmp}/prep.h5"],
                capture_output=True, text=True, cwd=ROOT)
            self.assertEqual(prep.returncode, 0, prep.stdout + prep.stderr)
            self.assertIn("Prepared bed:", prep.stdout + prep.stderr)
            with h5py.File(f"{tmp}/prep.h5", "r") as f:
                cfg = yaml.safe_load(f.attrs["config"])
            self.assertEqual(cfg["particles"]["model"], "rotating")
            self.assertEqual(cfg["particles"]["rolling_resistance"]["friction"], 1.0)
            self.assertEqual(cfg["contact"]["particle_particle"]["friction"], 0.2563)
            self.assertEqual(cfg["scene"]["dt"], 1.0e-4)
            with h5py.File(bed, "r") as f:
                mass = f["mass"][:]
                self.assertIn("w", f, "no angular velocities in the rotating bed")
                spin = f["w"][:]
                self.assertIn("pair_roll", f, "no rolling springs in the rotating bed")
            self.assertEqual(len(mass), 60)
            self.assertEqual(spin.shape, (60, 3))
            self.assertTrue(np.all(np.isfinite(spin)))

            # dem_service loads its checkpoint when it starts, before the master's parameters
            # arrive: the shipped config with this bed and this build's mesh set on its command line.
            soil_cfg = f"{ROOT}/configs/soil/hauler_load_rotating.yaml"
            st = load("configs/hauler_rotating.yaml")["participants"]["hauler"]["parameters"]["static_load"]
            static = f"{{mass: {st['mass']}, com: [{st['com'][0]}, {st['com'][1]}], gyration_radius: {st['gyration_radius']}}}"
            mesh = os.path.normpath(os.path.join(BIN, "..", "meshes", "hauler_body.stl"))
            self.assertTrue(os.path.exists(mesh), mesh)
            out = os.path.join(tmp, "run.h5")
            run = subprocess.run(
                [os.path.join(BIN, "cosim_master"), f"{ROOT}/configs/hauler_rotating.yaml",
                 "--set", "time.end=0.05", "--set", f"output.file={out}", "--set", "output.csv=",
                 "--set", "output.progress=off",
                 "--set", f"participants.soil.launch=[{BIN}/dem_service, {soil_cfg}, --set, scene.threads=1, "
                          f"--set, particles.checkpoint={bed}, --set, tools.0.mesh={mesh}]",
                 "--set", f"participants.soil.parameters.output.file={tmp}/soil.h5",
                 "--set", f"participants.hauler.launch=[{BIN}/hauler_adapter, {ROOT}/configs/hauler/machine.yaml]",
                 # the shipped load's weight as a rigid payload, so that the machine stands where
                 # the bed was prepared (the shipped pose) and the 60 grains are all the soil
                 "--set", f"participants.hauler.parameters.test_payload={static}",
                 "--set", f"participants.hauler.parameters.static_load={{mass: {mass.sum():.3f}, "
                          "com: [2.6, 0.35], gyration_radius: 1.0}",
                 "--set", f"bus.url=udpm://239.255.76.67:{PORT}?ttl=0"],
                capture_output=True, text=True, cwd=tmp)
            self.assertEqual(run.returncode, 0, run.stdout[-3000:] + run.stderr[-3000:])
            with h5py.File(out, "r") as f:
                t = f["time"][:]
                w = f["participants/soil/outputs/body"][:].reshape(len(t), -1)
            self.assertAlmostEqual(t[-1], 0.05, delta=1e-9)
            weight = mass.sum() * 9.81
            fz = -w[t > 0.025, 2].mean()  # the soil presses the body down: its F_z is negative
            self.assertAlmostEqual(fz / weight, 1.0, delta=0.01,
                                   msg=f"soil F_z on the body {fz:.1f} N against the grains' weight {weight:.1f} N")


if __name__ == "__main__":
    unittest.main()
