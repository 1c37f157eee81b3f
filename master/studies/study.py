#!/usr/bin/python3
"""Runs a parameter study: one cosim_master run per variant of a base config, then charts.

    /usr/bin/python3 master/studies/study.py STUDY.yaml [--only NAME ...] [--plot-only]
        [--members A-B] [--jobs N] [--detach]

The study file (docs/studies.md) names the base config, the common overrides, a reference
variant and the variants, each a map of dotted keys as `cosim_master --set` takes them.
Every variant writes OUTPUT_DIR/<name>.h5; the study writes OUTPUT_DIR/summary.json, the
charts (forces over time, work-precision) as PNG files and OUTPUT_DIR/report.md. A variant
that the master or a participant refuses (exit code 2, e.g. a DEM step above the safe limit)
is reported with the refusal's text instead of being plotted.

With an `ensemble` section every variant runs as several members (ensemble_run.py) and the
charts show bands, distances with intervals and verdicts (ensemble_charts.py).
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
    elif not prefix:
        pass  # an empty top-level `set: {}` overrides nothing (not `--set ={}`)
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
               "filter_seconds", "binary_dir", "ensemble", "outcomes", "members_dir"}
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
        extra = set(v) - {"label", "name", "set", "seed"}
        if extra:
            sys.exit(f"study: {path}: variant {v['label']}: unknown key(s) {sorted(extra)} (allowed: label, name, set, seed)")
        if "seed" in v and (not isinstance(v["seed"], int) or v["seed"] < 0):
            sys.exit(f"study: {path}: variant {v['label']}: seed must be an integer >= 0 (it shifts every member's seed)")
    names = [v["name"] for v in s["variants"] + ([s["reference"]] if s.get("reference") else [])]
    if len(set(names)) != len(names):
        sys.exit(f"study: {path}: two variants have the same name: {sorted(n for n in names if names.count(n) > 1)}")
    if "ensemble" in s:
        sys.path.insert(0, HERE)
        import ensemble
        try:
            ensemble.validate(s, f"study: {path}")
        except ensemble.StudyError as e:
            sys.exit(str(e))
    elif "outcomes" in s:
        sys.exit(f"study: {path}: outcomes need an ensemble section (docs/studies.md)")
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


def run_ensemble(study, a, out_dir, binary):
    sys.path.insert(0, HERE)
    import ensemble
    import ensemble_charts
    import ensemble_run
    if a.jobs is not None:
        if a.jobs < 1:
            sys.exit("study: --jobs must be >= 1")
        study["ensemble"]["jobs"] = a.jobs
    only_members = None
    if a.members:
        try:
            lo, _, hi = a.members.partition("-")
            only_members = set(range(int(lo), int(hi or lo) + 1))
        except ValueError:
            sys.exit(f"study: --members {a.members}: give a range like 0-3 or one member like 2")
    variants = []
    if study.get("reference"):
        study["reference"]["reference"] = True
        variants.append(study["reference"])
    variants += study["variants"]
    if a.only is not None:
        unknown = set(a.only) - {v["name"] for v in variants}
        if unknown:
            sys.exit(f"study: --only {sorted(unknown)}: no such variant (names: {[v['name'] for v in variants]})")
    run_list = variants if a.only is None else [v for v in variants if v["name"] in a.only]
    if a.plot_only:
        run_list = []
    try:
        # Members live in members_dir (default: output_dir); studies that share it share the
        # members of variants with the same name and command.
        members_dir = os.path.join(ROOT, study.get("members_dir", study["output_dir"]))
        metas = ensemble_run.run(study, run_list, members_dir, binary, ROOT, as_set_args, only_members)
        # Members of variants not run now: whatever earlier runs left in members_dir.
        for v in variants:
            if v["name"] not in metas:
                metas.update(ensemble_run.run(study, [v], members_dir, binary, ROOT, as_set_args, only_members=set()))
        results = ensemble_charts.make(study, variants, metas, out_dir)
    except ensemble.StudyError as e:
        sys.exit(f"study: {e}")
    failed = [r for r in results if r["failed"]]
    return 1 if failed else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("study")
    ap.add_argument("--only", nargs="*", help="run only these variant names (others are reused)")
    ap.add_argument("--plot-only", action="store_true", help="reuse the HDF5 files, only chart")
    ap.add_argument("--members", help="ensembles: run only members A-B (e.g. 0-3) on this host; the "
                    "others are taken from OUTPUT_DIR when present")
    ap.add_argument("--jobs", type=int, help="ensembles: members run at once (overrides ensemble.jobs)")
    ap.add_argument("--detach", action="store_true", help="run in the background, detached from this "
                    "terminal (survives the session); output in OUTPUT_DIR/study.log")
    a = ap.parse_args()
    study = load_study(a.study)
    out_dir = os.path.join(ROOT, study["output_dir"])
    os.makedirs(out_dir, exist_ok=True)
    binary = os.path.join(ROOT, study.get("binary_dir", "build/bin"), "cosim_master")
    if a.detach:
        log = os.path.join(out_dir, "study.log")
        args = [x for x in sys.argv if x != "--detach"]
        with open(log, "a") as f:
            p = subprocess.Popen([sys.executable] + args, stdout=f, stderr=subprocess.STDOUT,
                                 stdin=subprocess.DEVNULL, start_new_session=True, cwd=os.getcwd())
        print(f"study {study['name']}: running in the background as pid {p.pid}; follow it with "
              f"tail -f {log}")
        return 0
    if "ensemble" in study:
        return run_ensemble(study, a, out_dir, binary)
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
