#!/usr/bin/python3
"""Runs a parameter study: one cosim_master run per variant of a base config, then charts.

    /usr/bin/python3 master/studies/study.py STUDY.yaml [--only LABEL ...] [--plot-only]

The study file (docs/studies.md) names the base config, the common overrides, a reference
variant and the variants, each a map of dotted keys as `cosim_master --set` takes them.
Every variant writes OUTPUT_DIR/<name>.h5; the study writes OUTPUT_DIR/summary.json, the
charts (forces over time, work-precision) as PNG files and OUTPUT_DIR/report.md. A variant
that the master or a participant refuses (exit code 2, e.g. a DEM step above the safe limit)
is reported with the refusal's text instead of being plotted.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def flatten(prefix, value, out):
    """{a: {b: 1}} -> [('a.b', 1)] (lists and scalars are leaves)."""
    if isinstance(value, dict) and value:
        for k, v in value.items():
            flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    else:
        out.append((prefix, value))
    return out


def as_set_args(overrides):
    # JSON is YAML's flow style: numbers, strings, lists and maps pass through --set unchanged.
    return [a for key, value in flatten("", overrides or {}, []) for a in ("--set", f"{key}={json.dumps(value)}")]


def slug(label):
    return re.sub(r"[^A-Za-z0-9]+", "_", label).strip("_")


def load_study(path):
    with open(path) as f:
        s = yaml.safe_load(f)
    allowed = {"name", "description", "base", "output_dir", "set", "reference", "variants", "signals",
               "filter_seconds", "binary_dir"}
    unknown = set(s) - allowed
    if unknown:
        sys.exit(f"study: {path}: unknown key(s) {sorted(unknown)} (allowed: {sorted(allowed)})")
    for key in ("name", "base", "output_dir", "variants", "signals"):
        if key not in s:
            sys.exit(f"study: {path}: '{key}' is missing (docs/studies.md)")
    base_dir = os.path.dirname(os.path.abspath(path))
    s["base"] = os.path.normpath(os.path.join(base_dir, s["base"]))
    for v in s["variants"] + ([s["reference"]] if s.get("reference") else []):
        if "label" not in v:
            sys.exit(f"study: {path}: every variant needs a label")
        v.setdefault("name", slug(v["label"]))
        v.setdefault("set", {})
    return s


def run_variant(study, v, out_dir, binary):
    h5 = os.path.join(out_dir, v["name"] + ".h5")
    log = os.path.join(out_dir, v["name"] + ".log")
    cmd = [binary, study["base"], "--output", h5, "--set", "output.csv=",
           "--set", "output.progress=off"]
    cmd += as_set_args(study.get("set")) + as_set_args(v["set"])
    print(f"study {study['name']}: {v['label']} ...", flush=True)
    t0 = time.monotonic()
    with open(log, "w") as f:
        f.write(" ".join(cmd) + "\n")
        f.flush()
        code = subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT)
    wall = time.monotonic() - t0
    with open(log) as f:
        text = f.read()
    result = {"label": v["label"], "name": v["name"], "h5": h5, "log": log, "exit_code": code,
              "wall_seconds": wall, "set": v["set"]}
    if code == 2:
        # The refusal names the problem (for a DEM step: steps per contact and the safe dt).
        lines = [l for l in text.splitlines() if "refused" in l or "error" in l or "steps per contact" in l]
        result["refused"] = lines[-1] if lines else text.strip().splitlines()[-1]
        print(f"  refused: {result['refused']}")
    elif code != 0:
        tail = text.strip().splitlines()[-3:]
        result["failed"] = " | ".join(tail)
        print(f"  FAILED (exit {code}): {result['failed']}")
    else:
        print(f"  done in {wall:.1f} s")
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("study")
    ap.add_argument("--only", nargs="*", help="run only these variant names (others are reused)")
    ap.add_argument("--plot-only", action="store_true", help="reuse the HDF5 files, only chart")
    a = ap.parse_args()
    study = load_study(a.study)
    out_dir = os.path.join(ROOT, study["output_dir"])
    os.makedirs(out_dir, exist_ok=True)
    binary = os.path.join(ROOT, study.get("binary_dir", "build/bin"), "cosim_master")
    summary_path = os.path.join(out_dir, "summary.json")
    previous = {}
    if os.path.exists(summary_path):
        with open(summary_path) as f:
            previous = {r["name"]: r for r in json.load(f).get("runs", [])}
    runs = []
    todo = ([study["reference"]] if study.get("reference") else []) + study["variants"]
    for v in todo:
        if a.plot_only or (a.only is not None and v["name"] not in a.only):
            if v["name"] in previous:
                runs.append(previous[v["name"]])
                continue
            if a.plot_only:
                print(f"study: no earlier run of {v['name']}: left out (run it with --only {v['name']})")
                continue
        r = run_variant(study, v, out_dir, binary)
        r["reference"] = v is study.get("reference")
        runs.append(r)
    with open(summary_path, "w") as f:
        json.dump({"study": study["name"], "runs": runs}, f, indent=1)
    sys.path.insert(0, HERE)
    import charts
    charts.make(study, runs, out_dir)
    with open(summary_path, "w") as f:  # again, with the errors the charts computed
        json.dump({"study": study["name"], "runs": runs}, f, indent=1)
    failed = [r for r in runs if r["exit_code"] not in (0, 2)]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
