#!/usr/bin/python3
"""The main job's bucket motion as a tool-motion CSV for dem_run (time,x,y,z,qw,qx,qy,qz).

Reads the master's record of a main-job run (results/wheel_loader.csv, written by
`bash scripts/run.sh`) and writes the bucket pose the loader sent to the soil, so that the
main job's DEM can be stepped alone (dem_run, engine_ab) with the recorded maneuver:

    /usr/bin/python3 bench/dem/main_job_motion.py [results/wheel_loader.csv] [--out FILE] [--from T]

Default output: results/main_job_motion.csv (bench/dem/main_job.yaml reads it). --from T keeps
the poses from T s on with T as time 0: a run from a checkpoint at T that starts its clock at
0 (particles.keep_time: false), e.g. to compare DEM steps of different sizes, which a
checkpoint's clock (its step count times dt) would put at different times of the maneuver.
"""
import argparse
import csv
import sys

COLUMNS = ["time"] + [f"loader.bucket.{c}" for c in ("px", "py", "pz", "qw", "qx", "qy", "qz")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("record", nargs="?", default="results/wheel_loader.csv")
    ap.add_argument("--out", default="results/main_job_motion.csv")
    ap.add_argument("--from", dest="start", type=float, default=0.0,
                    help="first time kept, written as time 0 (default 0)")
    a = ap.parse_args()
    if not a.start >= 0:
        sys.exit(f"main_job_motion: --from must be a time >= 0 in s, got {a.start}")
    try:
        f = open(a.record, newline="")
    except OSError as e:
        sys.exit(f"main_job_motion: cannot read {a.record} ({e.strerror}); run `bash scripts/run.sh` first")
    with f:
        rows = csv.reader(f)
        head = next(rows, None)
        if head is None:
            sys.exit(f"main_job_motion: {a.record} is empty")
        missing = [c for c in COLUMNS if c not in head]
        if missing:
            sys.exit(f"main_job_motion: {a.record} has no column(s) {', '.join(missing)}: "
                     "not a wheel-loader record (cosim_master configs/wheel_loader.yaml)")
        idx = [head.index(c) for c in COLUMNS]
        out = []
        last_t = None
        for line, r in enumerate(rows, start=2):
            try:
                v = [float(r[i]) for i in idx]
            except (ValueError, IndexError):
                sys.exit(f"main_job_motion: {a.record} line {line}: not a number in the pose columns")
            if last_t is not None and v[0] <= last_t:
                continue  # keyframes must increase in time
            if v[0] < a.start - 1e-9:
                continue
            last_t = v[0]
            v[0] = max(0.0, v[0] - a.start)
            out.append(v)
    if len(out) < 2:
        sys.exit(f"main_job_motion: {a.record} has fewer than two poses" + (f" from {a.start:g} s" if a.start else ""))
    with open(a.out, "w") as g:
        g.write("time,x,y,z,qw,qx,qy,qz\n")
        for v in out:
            g.write(",".join(f"{x:.9g}" for x in v) + "\n")
    print(f"main_job_motion: {len(out)} poses, {out[0][0]:g}-{out[-1][0]:g} s -> {a.out}")


if __name__ == "__main__":
    main()
