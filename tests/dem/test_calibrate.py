"""scripts/calibrate.py without running the DEM: every bad input refused (exit 2) with a
message naming its key, the shipped targets accepted, and the response surface and its solver
against closed forms (docs/soil.md#calibration)."""
import copy
import importlib.util
import os
import re
import subprocess
import sys
import tempfile
import unittest

import yaml

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)
SCRIPT = os.path.join(ROOT, "scripts", "calibrate.py")
TARGETS = os.path.join(ROOT, "configs", "materials", "dry_sand.targets.yaml")
ROTATING = os.path.join(ROOT, "configs", "materials", "dry_sand_rotating.targets.yaml")

spec = importlib.util.spec_from_file_location("calibrate", SCRIPT)
calibrate = importlib.util.module_from_spec(spec)
spec.loader.exec_module(calibrate)


def check(doc_or_text, extra=()):
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "t.yaml")
        with open(path, "w") as f:
            f.write(doc_or_text if isinstance(doc_or_text, str) else yaml.safe_dump(doc_or_text))
        r = subprocess.run(["/usr/bin/python3", SCRIPT, path, "--check", "--bin", BIN, *extra],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        return r.returncode, r.stdout + r.stderr


with open(TARGETS) as f:
    BASE = yaml.safe_load(f)
with open(ROTATING) as f:
    ROT = yaml.safe_load(f)


def variant(edit, base=None):
    d = copy.deepcopy(BASE if base is None else base)
    edit(d)
    return d


class Refusals(unittest.TestCase):
    def refused(self, doc, *words):
        rc, msg = check(doc)
        self.assertEqual(rc, 2, msg)
        for w in words:
            self.assertIn(w, msg)

    def test_shipped_targets_accepted(self):
        rc, msg = check(BASE)
        self.assertEqual(rc, 0, msg)
        self.assertIn("input good", msg)

    def test_unknown_keys(self):
        self.refused(variant(lambda d: d["targets"].update(bulk_densty={"value": 1600, "tolerance": 20})),
                     "targets.bulk_densty: unknown key", "did you mean 'bulk_density'")
        self.refused(variant(lambda d: d.update(outptu="x.yaml")), "outptu: unknown key")
        self.refused(variant(lambda d: d["grains"].update(frction=0.2)), "grains.frction")
        self.refused(variant(lambda d: d["design"].update(sedes=3)), "design.sedes")

    def test_empty_targets(self):
        self.refused(variant(lambda d: d.update(targets={})), "targets: empty")
        self.refused(variant(lambda d: d.pop("targets")), "targets: empty")

    def test_targets_out_of_range(self):
        self.refused(variant(lambda d: d["targets"]["bulk_density"].update(value=2000)),
                     "targets.bulk_density.value", "packing fraction of 0.755")
        self.refused(variant(lambda d: d["targets"]["bulk_density"].update(value=1100)),
                     "targets.bulk_density.value")
        self.refused(variant(lambda d: d["targets"]["peak_friction_angle"].update(value=80)),
                     "targets.peak_friction_angle.value: 80")
        self.refused(variant(lambda d: d["targets"]["angle_of_repose"].update(value=5)),
                     "targets.angle_of_repose.value: 5")
        self.refused(variant(lambda d: d["targets"]["angle_of_repose"].update(tolerance=0)),
                     "targets.angle_of_repose.tolerance: 0 must be > 0")
        self.refused(variant(lambda d: d["targets"]["peak_friction_angle"].update(value="steep")),
                     "targets.peak_friction_angle.value: 'steep' is not a number")
        self.refused(variant(lambda d: d["targets"]["peak_friction_angle"].pop("tolerance")),
                     "targets.peak_friction_angle.tolerance: missing")

    def test_impossible_combinations(self):
        def steep(d):
            d["targets"]["angle_of_repose"]["value"] = 45
        self.refused(variant(steep), "angle_of_repose 45", "impossible combination")
        self.refused(variant(lambda d: d["grains"].update(normal_stiffness=4e7)),
                     "normal_stiffness or allowed_overlap, not both")
        self.refused(variant(lambda d: d["grains"].update(friction=0.3)),
                     "grains.friction: the calibration finds mu")
        self.refused(variant(lambda d: d["grains"].update(deposition_friction=0.1)),
                     "grains.deposition_friction: the calibration finds it")

    def test_bad_grains_and_design(self):
        self.refused(variant(lambda d: d["grains"].update(density=-1)), "grains.density")
        self.refused(variant(lambda d: d["grains"].update(radius={"min": 0.07, "max": 0.06})),
                     "grains.radius: max must be >= min")
        self.refused(variant(lambda d: d["grains"]["allowed_overlap"].update(overlap=0.5)),
                     "grains.allowed_overlap.overlap: 0.5 is above 0.1")
        self.refused(variant(lambda d: d["design"].update(friction=[0.2, 0.3])),
                     "design.friction: give a list of at least 3 values")
        self.refused(variant(lambda d: d["design"].update(friction=[0.2, 0.2, 0.3])),
                     "design.friction: values repeat")
        self.refused(variant(lambda d: d["design"].update(seeds=1)), "design.seeds: 1 is below 2")
        # One heap per design point: only where the surface keeps residual degrees of freedom.
        self.refused(variant(lambda d: d["design"].update(repose_seeds=1,
                                                          friction=[0.1, 0.2, 0.3])),
                     "design.repose_seeds: 1 x 3 design points", "no residual degrees of freedom")
        rc, msg = check(variant(lambda d: d["design"].update(repose_seeds=1)))  # 4 levels: 1 dof
        self.assertEqual(rc, 0, msg)
        self.refused(variant(lambda d: d.update(name="a b")), "name:")
        self.refused(variant(lambda d: d.pop("grains")), "grains: missing")

    def test_rotating_model(self):
        # The shipped rotating targets: mu_r fixed (1.0), mu and the deposition friction fitted.
        rc, msg = check(ROT)
        self.assertEqual(rc, 0, msg)
        cfg = calibrate.read_targets(ROTATING)
        self.assertEqual(cfg["grains"]["model"], "rotating")
        self.assertEqual(cfg["grains"]["mur"], 1.0)

        # The two-knob design that was run first (docs/soil_models.md): all three targets,
        # mu_r a knob over design.rolling_friction, one heap per point.
        def two_knobs(d):
            d["targets"]["angle_of_repose"] = {"value": 34, "tolerance": 2.0}
            d["grains"]["rolling_resistance"].pop("friction")
            d["design"]["rolling_friction"] = [0.6, 0.8, 1.0]
            d["design"]["repose_seeds"] = 1
        ROT2 = variant(two_knobs, ROT)
        rc, msg = check(ROT2)
        self.assertEqual(rc, 0, msg)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "t.yaml")
            with open(path, "w") as f:
                yaml.safe_dump(ROT2, f)
            cfg2 = calibrate.read_targets(path)
        self.assertNotIn("mur", cfg2["grains"])  # mu_r is a knob
        self.assertEqual(cfg2["design"]["rolling_friction"], [0.6, 0.8, 1.0])

        self.refused(variant(lambda d: d["grains"].update(model="spinning"), ROT),
                     "grains.model: 'spinning' is not allowed")
        self.refused(variant(lambda d: d["grains"].update(rolling_resistance={"friction": 0.1})),
                     "grains.rolling_resistance: needs grains.model: rotating")
        self.refused(variant(lambda d: d["design"].update(rolling_friction=[0.1, 0.2, 0.3])),
                     "design.rolling_friction: only the rotating model")
        self.refused(variant(lambda d: d["grains"]["rolling_resistance"].update(damping=2), ROT),
                     "grains.rolling_resistance.damping: 2 is above 1")
        self.refused(variant(lambda d: d["grains"]["rolling_resistance"].update(frction=0.1), ROT),
                     "grains.rolling_resistance.frction: unknown key", "did you mean 'friction'")
        self.refused(variant(lambda d: d["grains"]["rolling_resistance"].update(friction=1.5), ROT),
                     "grains.rolling_resistance.friction: 1.5 is above 1.0")
        self.refused(variant(lambda d: d["grains"]["rolling_resistance"].update(friction=0.2), ROT2),
                     "design.rolling_friction: grains.rolling_resistance.friction fixes mu_r")
        self.refused(variant(lambda d: d["design"].update(rolling_friction=[0.2, 0.5]), ROT2),
                     "design.rolling_friction: give a list of at least 3 values")
        self.refused(variant(lambda d: d["design"].update(rolling_friction=[0.0, 0.5, 0.8]), ROT2),
                     "design.rolling_friction: '0.0' must be a number in [0.01, 1.0]")
        self.refused(variant(lambda d: d["targets"].pop("angle_of_repose"), ROT2),
                     "grains.rolling_resistance.friction: missing", "both angle targets")
        mat = calibrate.material_doc(cfg2, 0.5, 0.1, 0.42)
        self.assertEqual(mat["particles"]["model"], "rotating")
        self.assertEqual(mat["particles"]["rolling_resistance"]["friction"], 0.42)
        self.assertNotIn("particles", calibrate.material_doc(calibrate.read_targets(TARGETS), 0.3, 0.1))

    def test_bad_files_and_options(self):
        rc, msg = check("targets: [unclosed\n")
        self.assertEqual(rc, 2, msg)
        self.assertIn("not valid YAML", msg)
        rc, msg = check(BASE, ["--jobs", "0"])
        self.assertEqual(rc, 2, msg)
        self.assertIn("--jobs", msg)
        with tempfile.TemporaryDirectory() as tmp:
            r = subprocess.run(["/usr/bin/python3", SCRIPT, TARGETS, "--check", "--bin", tmp],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            self.assertEqual(r.returncode, 2)
            self.assertIn("--bin: no dem_run", r.stderr)
        r = subprocess.run(["/usr/bin/python3", SCRIPT, "/no/such/targets.yaml", "--check"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.assertEqual(r.returncode, 2)
        self.assertIn("no such file", r.stderr)


class Method(unittest.TestCase):
    def test_surface_recovers_a_quadratic_and_solves_for_the_target(self):
        xs = [0.1, 0.2, 0.3] * 3
        noise = [0.3, -0.2, 0.1, -0.3, 0.2, -0.1, 0.0, 0.0, 0.0]
        ys = [20 + 60 * x + 40 * x * x + e for x, e in zip(xs, noise)]
        s = calibrate.Surface(xs, ys)
        self.assertAlmostEqual(s.c[0], 20, delta=1.5)
        self.assertAlmostEqual(s(0.2), 20 + 12 + 1.6, delta=0.3)
        # 20 + 60 x + 40 x^2 = 35 at x = (-60 + sqrt(3600 + 2400)) / 80 = 0.21824
        x, half = calibrate.solve({"a": s}, {"a": {"value": 35.0, "tolerance": 1.0}}, "friction")
        self.assertAlmostEqual(x, 0.21824, delta=0.01)
        self.assertGreater(half, 0.0)
        self.assertLess(half, 0.05)

    def test_two_targets_meet_in_the_middle_and_unreachable_is_refused(self):
        xs = [0.1, 0.2, 0.3, 0.1, 0.2, 0.3]
        a = calibrate.Surface(xs, [10 * x for x in xs])
        b = calibrate.Surface(xs, [10 * x + 0.4 for x in xs])
        # a wants x = 0.2, b wants x = 0.16; equal tolerances: the middle, 0.18.
        x, _ = calibrate.solve({"a": a, "b": b}, {"a": {"value": 2.0, "tolerance": 0.1},
                                                  "b": {"value": 2.0, "tolerance": 0.1}}, "friction")
        self.assertAlmostEqual(x, 0.18, delta=1e-3)
        with self.assertRaises(calibrate.Refused) as e:
            calibrate.solve({"a": a}, {"a": {"value": 9.0, "tolerance": 0.1}}, "friction")
        self.assertIn("outside what the design reaches", str(e.exception))

    def test_two_knobs_recover_a_quadratic_and_meet_both_targets(self):
        # Two angle surfaces over a 3 x 3 (mu, mu_r) design with two noisy replicates:
        # A = 10 + 40 mu + 10 mu_r + 5 mu mu_r, B = 12 + 4 mu + 30 mu_r - 6 mu_r^2.
        A = lambda x, y: 10 + 40 * x + 10 * y + 5 * x * y
        B = lambda x, y: 12 + 4 * x + 30 * y - 6 * y * y
        pts = [(x, y) for x in (0.2, 0.5, 0.8) for y in (0.1, 0.5, 0.9)] * 2
        noise = [0.2, -0.1, 0.15, -0.2, 0.1, 0.0, -0.15, 0.05, 0.1] * 2
        noise = noise[:9] + [-e for e in noise[9:]]
        sa = calibrate.Surface2(pts, [A(x, y) + e for (x, y), e in zip(pts, noise)])
        sb = calibrate.Surface2(pts, [B(x, y) - e for (x, y), e in zip(pts, noise)])
        self.assertAlmostEqual(sa(0.5, 0.5), A(0.5, 0.5), delta=0.2)
        self.assertAlmostEqual(sb(0.3, 0.7), B(0.3, 0.7), delta=0.3)
        self.assertEqual(sa.dof, 12)
        # Both at 30: Newton on the exact surfaces gives mu 0.3148, mu_r 0.6399 (A = B = 30.0).
        targets = {"a": {"value": 30.0, "tolerance": 1.0}, "b": {"value": 30.0, "tolerance": 1.0}}
        x, y, (hx, hy) = calibrate.solve2({"a": sa, "b": sb}, targets)
        self.assertAlmostEqual(A(x, y), 30.0, delta=0.3)
        self.assertAlmostEqual(B(x, y), 30.0, delta=0.3)
        self.assertAlmostEqual(x, 0.3148, delta=0.01)
        self.assertAlmostEqual(y, 0.6399, delta=0.01)
        self.assertGreater(hx, 0.0)
        self.assertLess(hx, 0.05)
        self.assertGreater(hy, 0.0)
        self.assertLess(hy, 0.05)
        # One Newton step from a miss returns to the solution of the exact surfaces.
        reached = {"a": {"mean": A(0.5, 0.3)}, "b": {"mean": B(0.5, 0.3)}}
        nx, ny = calibrate.newton2({"a": sa, "b": sb}, targets, reached, 0.5, 0.3)
        self.assertAlmostEqual(nx, 0.3148, delta=0.03)
        self.assertAlmostEqual(ny, 0.6399, delta=0.03)
        with self.assertRaises(calibrate.Refused) as e:
            calibrate.solve2({"a": sa, "b": sb}, {"a": {"value": 80.0, "tolerance": 1.0},
                                                  "b": {"value": 30.0, "tolerance": 1.0}})
        self.assertIn("design.rolling_friction", str(e.exception))

    def test_normal_stiffness_from_the_allowed_overlap(self):
        # k_N = 8 pi sigma / (phi Z delta), sigma = phi rho g h: 8 pi 2650 9.81 3 / (4.5 0.01)
        cfg = calibrate.read_targets(TARGETS)
        expect = 8 * 3.141592653589793 * 2650 * 9.81 * 3.0 / (4.5 * 0.01)
        self.assertAlmostEqual(calibrate.normal_stiffness(cfg) / expect, 1.0, places=9)


class ShippedMaterial(unittest.TestCase):
    def test_dry_sand_deposits_at_its_target_bulk_density(self):
        """configs/lab/deposition.yaml with the shipped dry_sand.yaml and dry_sand_rotating.yaml
        (seed 1, not one of the calibration's confirmation seeds; the rotating one brings its
        particle model): the bulk density within the recorded target's tolerance, the packing a
        frictional random one (below random close packing)."""
        for name in ("dry_sand.yaml", "dry_sand_rotating.yaml"):
            with open(os.path.join(ROOT, "configs", "materials", name)) as f:
                mat = yaml.safe_load(f)
            target = mat["calibration"]["targets"]["bulk_density"]
            with tempfile.TemporaryDirectory() as tmp:
                r = subprocess.run([os.path.join(BIN, "dem_run"), "configs/lab/deposition.yaml",
                                    "--set", f"materials.soil.file=../materials/{name}",
                                    "--set", f"output.file={tmp}/bed.h5"], cwd=ROOT,
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            self.assertEqual(r.returncode, 0, r.stderr[-2000:])
            m = re.search(r"Prepared bed: packing fraction ([0-9.]+), bulk density ([0-9.]+)",
                          r.stdout)
            self.assertIsNotNone(m, r.stdout[-2000:])
            packing, rho = float(m.group(1)), float(m.group(2))
            self.assertLessEqual(abs(rho - target["value"]), target["tolerance"], (name, rho))
            self.assertGreater(packing, 0.55, name)
            self.assertLess(packing, 0.63, name)


if __name__ == "__main__":
    unittest.main(verbosity=2)
