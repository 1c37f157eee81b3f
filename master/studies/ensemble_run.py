"""Runs the members of an ensemble study (called by study.py; docs/studies.md, "Ensembles").

Each member is one `cosim_master` run in OUTPUT_DIR/<variant>/m<i>.h5 with its log beside it and
a small JSON file (m<i>.json) with the command, exit code, wall time and CPU time (the master's
and its participants', from wait4). A member whose JSON records the same command and exit code 0
or 2 is not run again: an interrupted study, or one continued in another working session or on
another host that shares OUTPUT_DIR, computes only what is missing. Members run `jobs` at a
time, each on its own LCM URL (ensemble.bus / base_port + slot), so they do not hear each other.
"""
import json
import os
import subprocess
import time

import h5py
import numpy as np

import ensemble as ens


def member_paths(out_dir, variant, i):
    d = os.path.join(out_dir, variant["name"])
    return os.path.join(d, f"m{i}.h5"), os.path.join(d, f"m{i}.log"), os.path.join(d, f"m{i}.json")


def member_command(study, variant, i, binary, h5, as_set_args):
    cmd = [binary, study["base"], "--output", h5, "--set", "output.csv=", "--set", "output.progress=off"]
    cmd += as_set_args(study.get("set")) + as_set_args(variant["set"])
    cmd += as_set_args(ens.member_overrides(study["ensemble"], variant, i))
    return cmd


def cached(meta_path, cmd):
    if not os.path.exists(meta_path):
        return None
    try:
        with open(meta_path) as f:
            meta = json.load(f)
    except (OSError, ValueError):
        return None
    if meta.get("command") != cmd or meta.get("exit_code") not in (0, 2):
        return None
    if meta["exit_code"] == 0 and not os.path.exists(meta.get("h5", "")):
        return None
    return meta


def refusal(text):
    lines = [l for l in text.splitlines() if "refused" in l or "error" in l or "steps per contact" in l]
    return lines[-1] if lines else (text.strip().splitlines() or ["(no output)"])[-1]


def run(study, variants, out_dir, binary, root, as_set_args, only_members=None):
    """Runs the missing members; returns {variant name: [meta per member]}."""
    e = study["ensemble"]
    todo, metas = [], {v["name"]: [None] * e["members"] for v in variants}
    for v in variants:
        os.makedirs(os.path.join(out_dir, v["name"]), exist_ok=True)
        for i in range(e["members"]):
            h5, log, meta_path = member_paths(out_dir, v, i)
            cmd = member_command(study, v, i, binary, h5, as_set_args)
            meta = cached(meta_path, cmd)
            if meta is not None:
                metas[v["name"]][i] = meta
            elif only_members is None or i in only_members:
                todo.append((v, i, cmd, h5, log, meta_path))
    total = len(todo)
    if total:
        print(f"study {study['name']}: {total} member run(s) to do, {e['jobs']} at a time", flush=True)
    free = list(range(e["jobs"]))
    running = {}
    done = 0
    t_start = time.monotonic()
    while todo or running:
        while todo and free:
            v, i, cmd, h5, log, meta_path = todo.pop(0)
            slot = free.pop(0)
            full = cmd + ["--set", f"bus.url={ens.bus_url(e, slot)}"]
            f = open(log, "w")
            f.write(" ".join(full) + "\n")
            f.flush()
            p = subprocess.Popen(full, stdout=f, stderr=subprocess.STDOUT, cwd=root)
            running[p.pid] = (p, f, v, i, cmd, h5, log, meta_path, slot, time.monotonic())
        pid, status, usage = os.wait4(-1, 0)
        if pid not in running:
            continue
        p, f, v, i, cmd, h5, log, meta_path, slot, t0 = running.pop(pid)
        f.close()
        free.append(slot)
        code = os.waitstatus_to_exitcode(status)
        p.returncode = code
        wall = time.monotonic() - t0
        meta = {"variant": v["name"], "member": i, "command": cmd, "exit_code": code, "h5": h5,
                "log": log, "wall_seconds": wall, "cpu_seconds": usage.ru_utime + usage.ru_stime,
                "overrides": ens.member_overrides(e, v, i)}
        with open(log) as lf:
            text = lf.read()
        if code == 2:
            meta["refused"] = refusal(text)
        elif code != 0:
            meta["failed"] = " | ".join(text.strip().splitlines()[-3:])
        if code in (0, 2):  # a failed member is run again next time
            with open(meta_path, "w") as mf:
                json.dump(meta, mf, indent=1)
        metas[v["name"]][i] = meta
        done += 1
        elapsed = time.monotonic() - t_start
        eta = elapsed / done * (total - done)
        state = {0: "done", 2: "refused"}.get(code, f"FAILED (exit {code})")
        print(f"  [{done}/{total}] {v['label']}, member {i}: {state} in {wall:.1f} s "
              f"({meta['cpu_seconds']:.1f} CPU s); about {eta / 60:.1f} min left", flush=True)
        if code not in (0, 2):
            print(f"    {meta['failed']} (log: {log})", flush=True)
    return metas


def read_member(meta, paths):
    """(time, {path: series}, macro step) of a finished member."""
    with h5py.File(meta["h5"], "r") as f:
        t = f["time"][:]
        out = {}
        for path, column in paths:
            if path not in f:
                raise ens.StudyError(f"{meta['h5']} has no dataset {path} (docs/output.md lists them)")
            out[(path, column)] = np.asarray(f[path][:], dtype=float).reshape(len(t), -1)[:, column]
    return t, out
