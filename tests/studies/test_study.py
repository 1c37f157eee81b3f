"""The study runner on the oscillator: variants run, a refused variant is reported and not
plotted, charts and report are written, and the error falls with the macro step."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = sys.argv.pop(1)
BIN = sys.argv.pop(1)


class StudyRunner(unittest.TestCase):
    def test_empty_set_overrides_nothing(self):
        sys.path.insert(0, os.path.join(ROOT, "master", "studies"))
        import study
        self.assertEqual(study.as_set_args({}), [])
        self.assertEqual(study.as_set_args(None), [])
        self.assertEqual(study.as_set_args({"a": {"b": 1}, "c": {}}),
                         ["--set", "a.b=1", "--set", "c={}"])

    def test_oscillator_study(self):
        with tempfile.TemporaryDirectory() as tmp:
            study = os.path.join(tmp, "study.yaml")
            out = os.path.join(tmp, "out")
            with open(study, "w") as f:
                f.write(f"""
name: test
base: {ROOT}/configs/oscillator.yaml
output_dir: {out}
binary_dir: {BIN}
set: {{time.end: 0.6, participants.mass1.parameters.inner_step: 1.0e-4, participants.mass2.parameters.inner_step: 1.0e-4}}
reference: {{label: ref, set: {{time.macro_step: 1.0e-4}}}}
variants:
  - {{label: H2, set: {{time.macro_step: 2.0e-3}}}}
  - {{label: H1, set: {{time.macro_step: 1.0e-3}}}}
  - {{label: bad, set: {{time.macro_step: 1.5e-4}}}}
signals:
  - {{path: participants/mass1/outputs/x, label: x1}}
filter_seconds: 0
""")
            env = dict(os.environ, LCM_DEFAULT_URL="udpm://239.255.76.67:7799?ttl=0")
            r = subprocess.run(["/usr/bin/python3", f"{ROOT}/master/studies/study.py", study],
                               capture_output=True, text=True, env=env, cwd=ROOT)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            with open(os.path.join(out, "summary.json")) as f:
                runs = {x["label"]: x for x in json.load(f)["runs"]}
            self.assertEqual(runs["bad"]["exit_code"], 2)
            self.assertIn("not a multiple", runs["bad"]["refused"])
            for name in ("forces.png", "work_precision.png", "report.md"):
                self.assertGreater(os.path.getsize(os.path.join(out, name)), 500, name)
            report = open(os.path.join(out, "report.md")).read()
            self.assertIn("| bad | 2 |", report)
            # Jacobi (1,0) is first order: halving H about halves the error.
            e2, e1 = runs["H2"]["error_raw"], runs["H1"]["error_raw"]
            self.assertGreater(e2, 0)
            self.assertAlmostEqual(e2 / e1, 2.0, delta=0.4)


if __name__ == "__main__":
    unittest.main()
