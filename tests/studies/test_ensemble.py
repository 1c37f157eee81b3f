"""Ensembles in the study runner (docs/studies.md, "Ensembles"), on the dual-mass oscillator
where everything is known in closed form:

* members whose initial position is drawn from a normal distribution spread exactly as the
  linear theory says: std_t(x1) = |d x1(t) / d x1(0)| * std(draws), the sensitivity taken from
  the monolithic system's matrix exponential;
* two variants with the same settings but independent members are "within scatter"; a macro
  step whose error is known (a single run against the closed form) is "significant", and the
  distance of the ensemble means equals that error;
* members are cached: a rerun computes nothing, a deleted member is computed again alone;
* the statistics (Welch interval, permutation test) hold their nominal 95 % / 5 % rates on
  synthetic data;
* bad ensemble sections are refused with the key named.
"""
import json
import os
import subprocess
import sys
import tempfile
import unittest

import h5py
import numpy as np

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)
sys.path.insert(0, os.path.join(ROOT, "master", "studies"))
import ensemble  # noqa: E402

PORT = 7000 + os.getpid() % 500 * 2  # two bus slots of our own


def oscillator_matrix():
    m1 = m2 = 1.0
    c1 = c2 = 10.0
    d1 = d2 = 0.2
    cc, dc = 1000.0, 2.0
    return np.array([[0, 1, 0, 0], [-(c1 + cc) / m1, -(d1 + dc) / m1, cc / m1, dc / m1],
                     [0, 0, 0, 1], [cc / m2, dc / m2, -(c2 + cc) / m2, -(d2 + dc) / m2]])


def propagator(t):
    w, V = np.linalg.eig(oscillator_matrix())
    return np.real(V @ np.diag(np.exp(w * t)) @ np.linalg.inv(V))


STUDY = """
name: oscillator_ensemble
base: {root}/configs/oscillator.yaml
output_dir: {out}
binary_dir: {bin}
set: {{time.end: 0.5, predictors.kinematics.order: 1, predictors.force.order: 1,
      participants.mass1.parameters.inner_step: 1.0e-4, participants.mass2.parameters.inner_step: 1.0e-4}}
ensemble:
  members: 6
  jobs: 2
  base_port: {port}
  perturb:
    - {{keys: [participants.mass1.parameters.position, participants.mass2.parameters.coupled_position],
        normal: {{mean: 0.1, sigma: 1.0e-3}}, seed: 11}}
reference: {{label: ref, set: {{time.macro_step: 2.0e-4}}}}
variants:
  - {{label: same settings, name: same, set: {{time.macro_step: 2.0e-4}}, seed: 100}}
  - {{label: "H 2e-3, force constant", name: coarse, set: {{time.macro_step: 2.0e-3, predictors.force.order: 0}}}}
signals:
  - {{path: participants/mass1/outputs/x, label: x1, scale: 1000}}
outcomes:
  - {{name: "x1 peak after 0.05 s [mm]", path: participants/mass1/outputs/x, stat: max, from: 0.05, scale: 1000}}
  - {{name: "impulse of the coupling force [N s]", path: participants/mass2/outputs/force, stat: integral}}
filter_seconds: 0
"""


class Ensemble(unittest.TestCase):
    def run_study(self, path, *extra):
        env = dict(os.environ, LCM_DEFAULT_URL=f"udpm://239.255.76.67:{PORT + 400}?ttl=0")
        return subprocess.run(["/usr/bin/python3", f"{ROOT}/master/studies/study.py", path, *extra],
                              capture_output=True, text=True, env=env, cwd=ROOT)

    def test_oscillator_ensemble(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "out")
            study = os.path.join(tmp, "study.yaml")
            with open(study, "w") as f:
                f.write(STUDY.format(root=ROOT, out=out, bin=BIN, port=PORT))
            r = self.run_study(study)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            self.assertIn("18 member run(s) to do", r.stdout)
            with open(os.path.join(out, "summary.json")) as f:
                s = json.load(f)
            grid = np.array(s["grid"])
            self.assertAlmostEqual(grid[0], 0.0)
            self.assertAlmostEqual(grid[-1], 0.5)

            # The spread of the reference ensemble against the linear theory.
            draws = []
            for i in range(6):
                with open(os.path.join(out, "ref", f"m{i}.json")) as f:
                    ov = json.load(f)["overrides"]
                self.assertEqual(ov["participants.mass1.parameters.position"],
                                 ov["participants.mass2.parameters.coupled_position"])
                draws.append(ov["participants.mass1.parameters.position"])
            self.assertEqual(len(set(draws)), 6)
            g = np.array([propagator(t)[0, 0] for t in grid])  # d x1(t) / d x1(0)
            std = np.array(s["bands"]["ref"]["std"][0]) / 1000
            mean = np.array(s["bands"]["ref"]["mean"][0]) / 1000
            expect_std = np.abs(g) * np.std(draws, ddof=1)
            expect_mean = g * np.mean(draws)
            rel = lambda a, b: np.sqrt(np.sum((a - b) ** 2) / np.sum(b ** 2))  # noqa: E731
            # Jacobi (1,1) at H = 2e-4 s is within about 1.2e-4 of the monolithic solution here
            # (second order: 3e-5 at 1e-4 s); a wrong ddof (x1.095), a missing scale or a
            # mixed-up member would be off by far more.
            print(f"ensemble spread against the linear theory: std {rel(std, expect_std):.2e}, "
                  f"mean {rel(mean, expect_mean):.2e} (relative RMS)")
            self.assertLess(rel(std, expect_std), 1e-3)
            self.assertLess(rel(mean, expect_mean), 1e-3)

            v = {x["name"]: x for x in s["variants"]}
            same, coarse = v["same"]["comparison"], v["coarse"]["comparison"]
            self.assertEqual(same["verdict"], "within scatter")
            self.assertGreater(same["p_value"], 0.05)
            self.assertLess(same["distance"], 3 * same["floor"])
            # One run's scatter: the RMS of the variant's standard deviation over the RMS of the
            # reference's mean.
            std_same = np.array(s["bands"]["same"]["std"][0])
            mean_ref = np.array(s["bands"]["ref"]["mean"][0])
            self.assertAlmostEqual(same["scatter_variant"], np.sqrt(np.sum(std_same ** 2) / np.sum(mean_ref ** 2)), 12)

            # The known error of the coarse variant: one unperturbed run against the closed form.
            h5 = os.path.join(tmp, "coarse_single.h5")
            cmd = [os.path.join(BIN, "cosim_master"), f"{ROOT}/configs/oscillator.yaml", "--output", h5,
                   "--set", "output.csv=", "--set", "output.progress=off", "--set", "time.end=0.5",
                   "--set", "time.macro_step=2e-3", "--set", "predictors.kinematics.order=1",
                   "--set", "predictors.force.order=0", "--set", f"bus.url=udpm://239.255.76.67:{PORT}?ttl=0"]
            p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
            with h5py.File(h5, "r") as f:
                t = f["time"][:]
                x1 = f["participants/mass1/outputs/x"][:].reshape(-1)
            exact = np.array([propagator(tt)[0, 0] * 0.1 for tt in t])
            known = rel(x1, exact)
            self.assertGreater(known, 0.1)  # a coarse step: an error far above the 1 % scatter
            self.assertEqual(coarse["verdict"], "significant")
            self.assertLess(coarse["p_value"], 0.05)
            self.assertAlmostEqual(coarse["distance"] / known, 1.0, delta=0.02)
            self.assertLessEqual(coarse["distance_ci"][0], coarse["distance"])
            self.assertGreaterEqual(coarse["distance_ci"][1], coarse["distance"])

            # Outcomes: the impulse of a linear system is linear in the draws too.
            self.assertIn("impulse of the coupling force [N s]", v["ref"]["outcomes"])
            d = v["coarse"]["outcome_differences"]["x1 peak after 0.05 s [mm]"]
            self.assertTrue(d["significant"])
            self.assertFalse(v["same"]["outcome_differences"]["x1 peak after 0.05 s [mm]"]["significant"])
            for name in ("forces.png", "work_precision.png", "outcomes.png", "report.md"):
                self.assertGreater(os.path.getsize(os.path.join(out, name)), 500, name)
            with open(os.path.join(out, "report.md")) as f:
                report = f.read()
            self.assertIn("| same settings | 6/6 |", report)
            self.assertIn("significant", report)

            # Cached: nothing to run again, the same numbers.
            r2 = self.run_study(study)
            self.assertEqual(r2.returncode, 0, r2.stdout + r2.stderr)
            self.assertNotIn("member run(s) to do", r2.stdout)
            with open(os.path.join(out, "summary.json")) as f:
                s2 = json.load(f)
            self.assertEqual(s2["bands"], s["bands"])
            # A lost member is computed again, alone.
            os.remove(os.path.join(out, "coarse", "m3.json"))
            r3 = self.run_study(study)
            self.assertIn("1 member run(s) to do", r3.stdout)
            self.assertIn("member 3: done", r3.stdout)
            # --members restricts what this host computes; the rest is reported as missing.
            os.remove(os.path.join(out, "same", "m5.json"))
            r4 = self.run_study(study, "--members", "0-4")
            self.assertEqual(r4.returncode, 0, r4.stdout + r4.stderr)
            self.assertNotIn("member run(s) to do", r4.stdout)
            with open(os.path.join(out, "report.md")) as f:
                self.assertIn("not run yet: members [5]", f.read())

    def test_smoothing_averages_over_time_at_uneven_steps(self):
        # An adaptive macro step's samples: 0.5 ms apart in the first half, 5 ms in the second.
        # The centred moving average of sin(w t) over T is sin(w t) sin(w T / 2) / (w T / 2).
        w, T = 2 * np.pi * 3, 0.1
        t = np.concatenate([np.arange(0, 0.5, 5e-4), np.arange(0.5, 1.0 + 1e-9, 5e-3)])
        got = ensemble.smooth(t, np.sin(w * t), T)
        exact = np.sin(w * t) * np.sin(w * T / 2) / (w * T / 2)
        inner = (t > T) & (t < 1.0 - T)
        self.assertLess(float(np.abs(got - exact)[inner].max()), 0.02)
        # Even samples take the count-based path as before.
        te = np.linspace(0, 1, 2001)
        ge = ensemble.smooth(te, np.sin(w * te), T)
        ee = np.sin(w * te) * np.sin(w * T / 2) / (w * T / 2)
        self.assertLess(float(np.abs(ge - ee)[(te > T) & (te < 1 - T)].max()), 0.02)

    def test_bad_ensemble_sections(self):
        cases = [
            ("members: 1", "ensemble.members must be an integer >= 2"),
            ("membres: 4", "unknown key(s) ['membres']"),
            ("perturb: [{key: a.b, value: 1}]", "every entry is a fixed value"),
            ("perturb: [{key: a.b, normal: {mean: 0, sigma: 0}}]", "normal must be"),
            ("perturb: [{key: a.b, seed: -1}]", "seed must be an integer >= 0"),
            ("perturb: [{value: 3, seed: 1}]", "give key"),
            ("window: [2, 1]", "ensemble.window"),
        ]
        with tempfile.TemporaryDirectory() as tmp:
            for text, message in cases:
                base = {"members": 4, "perturb": "[{key: participants.mass1.parameters.position, normal: {mean: 0.1, sigma: 1.0e-3}}]"}
                key = text.split(":")[0]
                base.pop(key, None)
                lines = [f"  {k}: {v}" for k, v in base.items()] + [f"  {text}"]
                path = os.path.join(tmp, "bad.yaml")
                with open(path, "w") as f:
                    f.write(f"name: bad\nbase: {ROOT}/configs/oscillator.yaml\noutput_dir: {tmp}/o\n"
                            f"variants: [{{label: a}}]\nsignals: [{{path: x, label: x}}]\nensemble:\n"
                            + "\n".join(lines) + "\n")
                r = self.run_study(path)
                self.assertNotEqual(r.returncode, 0, text)
                self.assertIn(message, r.stderr, text)
                self.assertFalse(os.path.exists(os.path.join(tmp, "o", "a")), text)

    def test_statistics_hold_their_nominal_rates(self):
        rng = np.random.default_rng(2026)
        # Welch's 95 % interval covers the true difference of means (here 0.3) 95 % of the time.
        reps, covered = 1000, 0
        for _ in range(reps):
            a = rng.normal(0.3, 1.0, 6)
            b = rng.normal(0.0, 2.0, 8)
            w = ensemble.welch(a, b)
            covered += w["ci"][0] <= 0.3 <= w["ci"][1]
        self.assertAlmostEqual(covered / reps, 0.95, delta=0.025)  # 3.5 binomial sigma
        # The permutation test rejects a true null hypothesis 5 % of the time or less (discrete:
        # 6 + 6 members give p-values in steps of 2/924), and finds a shift of the mean by 0.6
        # standard deviations of one member (at 20 time points) in most trials.
        reps, rejected, found = 300, 0, 0
        for _ in range(reps):
            R = rng.normal(1.0, 0.1, (6, 1, 20))
            X0 = rng.normal(1.0, 0.1, (6, 1, 20))
            X1 = rng.normal(1.0, 0.1, (6, 1, 20)) + 0.06  # 0.6 sigma of one member, at 20 points
            rejected += ensemble.compare(X0, R, bootstrap=50)["verdict"] == "significant"
            found += ensemble.compare(X1, R, bootstrap=50)["verdict"] == "significant"
        self.assertLess(rejected / reps, 0.05 + 3 * np.sqrt(0.05 * 0.95 / reps))
        self.assertGreater(found / reps, 0.6)  # power about 0.85


if __name__ == "__main__":
    unittest.main()
