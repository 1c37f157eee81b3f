#!/usr/bin/python3
"""Side-by-side benchmark against LAMMPS (driven by side_by_side.sh; method in
docs/performance.md).

1. Prepares each scene once with dem_side_by_side (our checkpoint + a LAMMPS data file with
   the same particles; cached in --dir).
2. Physics check on the 10k gas: kinetic energy and mean contacts per particle of both codes
   over the first 0.1 s. Fails (exit 1) when they disagree beyond the stated tolerances.
3. Timing: each scene, rebuild policy ("needed": our skin guard / LAMMPS `check yes`; "every 5":
   our broad_phase_interval 5 / LAMMPS `every 5 delay 0 check no`), 1 thread vs 1 rank and
   2 threads vs 2 ranks, N repeats with ours and LAMMPS alternating. Only the stepping is timed
   (ours: 20 warm-up steps, then the clock; LAMMPS: `run 20`, then the `Loop time` of the next
   `run`). Prints the medians, the ratio ours/LAMMPS (median of the per-repeat ratios) and the
   cost per particle-step in core nanoseconds.
4. With --cost-ratio: ours only, 1 thread, the smallest and the largest of --sizes timed in
   turn (small, large, small, large, ...) for --repeats rounds and each rebuild policy; prints
   the cost per particle-step of both and their ratio per round, and the median ratio. Runs
   minutes apart on a shared VM differ by more than the goal's margin (1.3x), so the two sizes
   are compared only within a round.
"""
import argparse
import datetime
import json
import os
import platform
import re
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# Tolerances of the physics check (10k gas, first 0.1 s, sampled every 2 ms). The trajectories
# of two codes diverge (chaos), so the check compares ensemble quantities: the kinetic energy
# at every sample and the mean contacts per particle averaged over the samples.
KE_TOL = 0.05        # relative, at every sample
CONTACTS_TOL = 0.10  # relative, time average over 0.1 s

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMP_NUM_THREADS": "1"}


def parse_size(text):
    text = text.strip().lower()
    mult = 1
    if text.endswith("k"):
        mult, text = 1000, text[:-1]
    elif text.endswith("m"):
        mult, text = 1000000, text[:-1]
    return int(round(float(text) * mult))


def label(n):
    return f"{n / 1e6:g}M" if n >= 1000000 else f"{n // 1000}k"


def read_box(path):
    box = {}
    with open(path) as f:
        for line in f:
            k, v = line.split()
            box[k] = v
    return box


def lammps_input(stem, box, ranks_policy, steps=None, trace=None):
    """LAMMPS input for the scene at `stem`: same particles, contact law, walls, dt, skin."""
    kn = float(box["stiffness"])
    kt = kn * 2.0 / 7.0
    gn = float(box["gamma_n"])
    gt = gn / 2.0
    mu = float(box["friction"])
    law = f"{kn!r} {kt!r} {gn!r} {gt!r} {mu!r} 1"
    sx, sy, sz = float(box["sx"]), float(box["sy"]), float(box["sz"])
    lines = [
        "units si",
        "atom_style sphere",
        "atom_modify map array",
        "boundary f f f",
        "comm_modify vel yes",
        f"read_data {stem}.data",
        f"pair_style gran/hooke/history {law}",
        "pair_coeff * *",
        f"neighbor {float(box['skin'])!r} bin",
        ("neigh_modify every 1 delay 0 check yes" if ranks_policy == 0
         else f"neigh_modify every {ranks_policy} delay 0 check no"),
        f"timestep {float(box['dt'])!r}",
        "fix integrate all nve",  # translation only: no rotation, like ours
        f"fix wx all wall/gran hooke/history {law} xplane 0.0 {sx!r}",
        f"fix wy all wall/gran hooke/history {law} yplane 0.0 {sy!r}",
        f"fix wz all wall/gran hooke/history {law} zplane 0.0 " + (f"{sz!r}" if sz > 0 else "NULL"),
    ]
    if box["gravity"] == "1":
        lines.append("fix gravity all gravity 9.81 vector 0 0 -1")
    if trace:
        duration, every = trace
        dt = float(box["dt"])
        lines += [
            "compute ke all ke",
            "compute cn all contact/atom",
            "compute cnsum all reduce sum c_cn",
            "thermo_style custom step c_ke c_cnsum atoms",
            "thermo_modify format float %.10g",
            f"thermo {int(round(every / dt))}",
            f"run {int(round(duration / dt))}",
        ]
    else:
        lines += ["thermo 1000000", "run 20", f"run {steps}"]
    return "\n".join(lines) + "\n"


def run_lammps(script, ranks, workdir, name):
    path = os.path.join(workdir, name + ".in")
    with open(path, "w") as f:
        f.write(script)
    cmd = ["mpirun", "-np", str(ranks), "--bind-to", "core",
           "lmp", "-in", path, "-log", os.path.join(workdir, name + ".log"), "-screen", "none"]
    env = dict(os.environ, **MPI_ENV)
    res = subprocess.run(cmd, env=env, capture_output=True, text=True)
    log = open(os.path.join(workdir, name + ".log")).read() if os.path.exists(
        os.path.join(workdir, name + ".log")) else ""
    if res.returncode != 0 or "ERROR" in log:
        sys.exit(f"side_by_side: LAMMPS failed ({' '.join(cmd)}):\n{res.stderr[-2000:]}\n"
                 f"{log[-2000:]}")
    return log


def ours(args, *opts):
    cmd = [args.dem, *opts]
    res = subprocess.run(cmd, capture_output=True, text=True,
                         env=dict(os.environ, OMP_NUM_THREADS="2"))
    if res.returncode != 0:
        sys.exit(f"side_by_side: {' '.join(cmd)} failed:\n{res.stderr[-2000:]}")
    return res.stdout


def prepare(args, kind, n):
    stem = os.path.join(args.dir, f"{kind}_{n}")
    if not os.path.exists(stem + ".box"):
        print(f"preparing {kind} {label(n)} (cached in {args.dir}) ...", flush=True)
        res = subprocess.run([args.dem, "prepare", "--kind", kind, "--n", str(n), "--dir",
                              args.dir], stderr=subprocess.PIPE, text=True)
        if res.returncode != 0:
            sys.exit(f"side_by_side: prepare {kind} {n} failed:\n{res.stderr[-2000:]}")
    return stem, read_box(stem + ".box")


def physics_check(args):
    n = 10000
    stem, box = prepare(args, "gas", n)
    duration, every = 0.1, 0.002
    print(f"\n== physics check: {label(n)} gas, first {duration} s, 1 thread vs 1 rank, "
          f"rebuild every 5 steps ==", flush=True)
    out = ours(args, "trace", "--kind", "gas", "--n", str(n), "--dir", args.dir, "--threads",
               "1", "--interval", "5", "--duration", str(duration), "--every", str(every))
    mine = [tuple(map(float, line.split())) for line in out.splitlines() if line.strip()]
    log = run_lammps(lammps_input(stem, box, 5, trace=(duration, every)), 1, args.dir,
                     "check_gas")
    theirs = []
    header = False
    for line in log.splitlines():
        cols = line.split()
        if cols[:3] == ["Step", "c_ke", "c_cnsum"]:
            header = True
            continue
        if header and len(cols) == 4 and re.fullmatch(r"\d+", cols[0]):
            atoms = float(cols[3])
            if atoms != n:
                sys.exit(f"side_by_side: LAMMPS lost atoms in the gas ({atoms:g} of {n})")
            theirs.append((int(cols[0]) * float(box["dt"]), float(cols[1]), float(cols[2]) / n))
        elif header and cols[:2] == ["Loop", "time"]:
            header = False
    if len(theirs) != len(mine):
        sys.exit(f"side_by_side: {len(mine)} samples from ours, {len(theirs)} from LAMMPS")
    worst = 0.0
    print(f"{'t [s]':>7} {'KE ours [J]':>12} {'KE LAMMPS':>12} {'rel diff':>9} "
          f"{'contacts/p ours':>16} {'LAMMPS':>8}")
    for (t, ke1, c1), (_, ke2, c2) in zip(mine, theirs):
        d = abs(ke1 - ke2) / ke2
        worst = max(worst, d)
        if round(t / every) % 5 == 0:
            print(f"{t:7.3f} {ke1:12.5g} {ke2:12.5g} {d:9.2%} {c1:16.4f} {c2:8.4f}")
    c_ours = statistics.fmean(c for _, _, c in mine)
    c_lmp = statistics.fmean(c for _, _, c in theirs)
    dc = abs(c_ours - c_lmp) / c_lmp
    ke_end = mine[-1][1] / mine[0][1]
    print(f"kinetic energy: worst relative difference {worst:.2%} (tolerance {KE_TOL:.0%}); "
          f"ours falls to {ke_end:.3f} of its start")
    print(f"mean contacts per particle over {duration} s: ours {c_ours:.4f}, LAMMPS {c_lmp:.4f},"
          f" relative difference {dc:.2%} (tolerance {CONTACTS_TOL:.0%})")
    ok = worst <= KE_TOL and dc <= CONTACTS_TOL
    result = {"ke_worst_rel": worst, "contacts_ours": c_ours, "contacts_lammps": c_lmp,
              "contacts_rel": dc, "ke_end_over_start": ke_end, "ok": ok}
    if not ok:
        print("side_by_side: FAILED: ours and LAMMPS disagree on the physics of the gas; "
              "the timings would not compare like with like", file=sys.stderr)
        sys.exit(1)
    print("physics check passed", flush=True)
    return result


def steps_for(args, n):
    if args.steps:
        return args.steps
    steps = max(100, int(args.work / n))
    return steps - steps % 5


def time_ours(args, kind, n, threads, policy, steps):
    out = ours(args, "run", "--kind", kind, "--n", str(n), "--dir", args.dir, "--threads",
               str(threads), "--interval", str(policy), "--steps", str(steps),
               "--thread-wait", args.thread_wait, "--close-margin", str(args.close_margin))
    f = out.split()
    return (float(f[f.index("rate") + 1]), int(f[f.index("rebuilds") + 1]),
            float(f[f.index("cpu_share") + 1]))


def time_lammps(args, stem, box, n, ranks, policy, steps):
    log = run_lammps(lammps_input(stem, box, policy, steps=steps), ranks, args.dir,
                     f"time_{os.path.basename(stem)}_{ranks}_{policy}")
    loops = re.findall(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps", log)
    seconds, procs, nsteps = loops[-1]
    assert int(procs) == ranks and int(nsteps) == steps
    builds = re.findall(r"Neighbor list builds = (\d+)", log)
    share = re.findall(r"([0-9.]+)% CPU use with", log)
    return (n * steps / float(seconds), int(builds[-1]) if builds else -1,
            float(share[-1]) / 100 if share else float("nan"))


def timing(args, scenes):
    rows = []
    for kind, n in scenes:
        stem, box = prepare(args, kind, n)
        steps = steps_for(args, n)
        for policy in (0, 5):
            for threads in args.threads:
                r_ours, r_lmp, ratios, reb_o, reb_l, sh_o, sh_l = [], [], [], 0, 0, [], []
                for _ in range(args.repeats):
                    a, reb_o, s_o = time_ours(args, kind, n, threads, policy, steps)
                    b, reb_l, s_l = time_lammps(args, stem, box, n, threads, policy, steps)
                    r_ours.append(a)
                    r_lmp.append(b)
                    ratios.append(a / b)
                    sh_o.append(s_o)
                    sh_l.append(s_l)
                row = {"scene": f"{label(n)} {'gas' if kind == 'gas' else 'settled bed'}",
                       "n": n, "policy": "when needed" if policy == 0 else "every 5",
                       "threads": threads, "steps": steps,
                       "ours": statistics.median(r_ours), "lammps": statistics.median(r_lmp),
                       "ratio": statistics.median(ratios), "ours_all": r_ours,
                       "lammps_all": r_lmp, "rebuilds_ours": reb_o, "rebuilds_lammps": reb_l,
                       "cpu_share_ours": statistics.median(sh_o),
                       "cpu_share_lammps": statistics.median(sh_l),
                       "cpu_share_ours_all": sh_o, "cpu_share_lammps_all": sh_l}
                row["ns_ours"] = 1e9 * threads / row["ours"]
                row["ns_lammps"] = 1e9 * threads / row["lammps"]
                rows.append(row)
                print(f"  {row['scene']:>16}  {row['policy']:>11}  {threads}/{threads}: ours "
                      f"{row['ours']:.3g}, LAMMPS {row['lammps']:.3g} particle-steps/s, "
                      f"ratio {row['ratio']:.2f}  (ratios {', '.join(f'{r:.2f}' for r in ratios)};"
                      f" broad phases {reb_o} vs neighbour builds {reb_l} in {steps} steps;"
                      f" CPU share {', '.join(f'{x:.2f}' for x in sh_o)} vs"
                      f" {', '.join(f'{x:.2f}' for x in sh_l)})",
                      flush=True)
    return rows


def cost_ratio(args, sizes):
    small, large = min(sizes), max(sizes)
    for n in (small, large):
        prepare(args, "bed", n)
    print(f"\n== cost per particle-step, 1 thread: {label(large)} against {label(small)}, "
          f"{args.repeats} rounds, the two sizes in turn ==", flush=True)
    rows = []
    for policy in (0, 5):
        ns_small, ns_large, ratios = [], [], []
        for k in range(args.repeats):
            a, _, _ = time_ours(args, "bed", small, 1, policy, steps_for(args, small))
            b, _, _ = time_ours(args, "bed", large, 1, policy, steps_for(args, large))
            ns_small.append(1e9 / a)
            ns_large.append(1e9 / b)
            ratios.append(ns_large[-1] / ns_small[-1])
            print(f"  {'when needed' if policy == 0 else 'every 5':>11}  round {k + 1}: "
                  f"{label(small)} {ns_small[-1]:.0f}, {label(large)} {ns_large[-1]:.0f} "
                  f"core-ns per particle-step, ratio {ratios[-1]:.2f}", flush=True)
        rows.append({"policy": "when needed" if policy == 0 else "every 5",
                     "small": small, "large": large, "ns_small": ns_small,
                     "ns_large": ns_large, "ratios": ratios,
                     "ratio": statistics.median(ratios)})
    out = [f"| rebuild | {label(small)} [core-ns per particle-step] | {label(large)} [core-ns] "
           f"| {label(large)} / {label(small)} per round | median |",
           "| --- | --- | --- | --- | ---: |"]
    for r in rows:
        out.append(f"| {r['policy']} | {', '.join(f'{x:.0f}' for x in r['ns_small'])} | "
                   f"{', '.join(f'{x:.0f}' for x in r['ns_large'])} | "
                   f"{', '.join(f'{x:.2f}' for x in r['ratios'])} | **{r['ratio']:.2f}** |")
    return rows, "\n".join(out)


def table(rows):
    out = ["| scene | rebuild | threads vs ranks | ours [particle-steps/s] | LAMMPS "
           "[particle-steps/s] | ours/LAMMPS | ours [core-ns per particle-step] | LAMMPS "
           "[core-ns] | rebuilds in the timed steps (ours / LAMMPS) | CPU share (ours / LAMMPS) |",
           "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        out.append(f"| {r['scene']} | {r['policy']} | {r['threads']} vs {r['threads']} | "
                   f"{r['ours']:.3g} | {r['lammps']:.3g} | **{r['ratio']:.2f}** | "
                   f"{r['ns_ours']:.0f} | {r['ns_lammps']:.0f} | "
                   f"{r['rebuilds_ours']} / {r['rebuilds_lammps']} of {r['steps']} steps | "
                   f"{r['cpu_share_ours']:.2f} / {r['cpu_share_lammps']:.2f} |")
    return "\n".join(out)


def write_results(args, name, started, cpu, text, fields, title):
    """Prints the table and writes it (NAME_STAMP.md) with its data (NAME_STAMP.json)."""
    ended = datetime.datetime.now(datetime.timezone.utc)
    print("\n" + text)
    stem = os.path.join(args.dir, f"{name}_{started:%Y%m%d_%H%M}")
    with open(stem + ".json", "w") as f:
        json.dump({"started": started.isoformat(), "ended": ended.isoformat(), "cpu": cpu,
                   "cores": os.cpu_count(), "load_average_end": os.getloadavg(), **fields},
                  f, indent=1)
    with open(stem + ".md", "w") as f:
        f.write(f"{title}, {os.cpu_count()} x {cpu}, {started:%Y-%m-%d %H:%M}-{ended:%H:%M} "
                f"UTC, load average at the end {os.getloadavg()[0]:.1f}\n\n{text}\n")
    print(f"\nwritten to {stem}.md and .json ({(ended - started).total_seconds() / 60:.1f} min)")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", default="10k,150k", help="settled beds, e.g. 10k,150k,600k,1.2M")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", default="1,2", help="thread counts = MPI rank counts")
    p.add_argument("--steps", type=int, default=0, help="timed steps (default: --work / n)")
    p.add_argument("--cost-ratio", action="store_true",
                   help="ours only: the cost per particle-step at the largest of --sizes "
                        "against the smallest, 1 thread, the two in turn (no LAMMPS; "
                        "--threads and --gas-timing do not apply)")
    p.add_argument("--work", type=float, default=4e7,
                   help="particle-steps per timed run when --steps is not given")
    p.add_argument("--gas-timing", action="store_true", help="time the 10k gas too")
    p.add_argument("--skip-check", action="store_true", help="skip the physics check")
    p.add_argument("--dir", default="results/bench_lammps")
    p.add_argument("--thread-wait", default="yield", choices=["yield", "passive", "brief", "spin"],
                   help="how our idle threads wait (scene.thread_wait; default: the product's)")
    p.add_argument("--close-margin", type=float, default=0.0,
                   help="performance.close_margin of our runs (fraction of r; 0: every candidate)")
    p.add_argument("--dem", required=True, help="path of dem_side_by_side")
    args = p.parse_args()
    if args.repeats < 1:
        sys.exit(f"side_by_side: --repeats {args.repeats}: give at least 1")
    if args.work <= 0 or args.steps < 0:
        sys.exit("side_by_side: --work must be positive and --steps 0 (from --work) or more")
    args.threads = [int(t) for t in args.threads.split(",")]
    sizes = [parse_size(s) for s in args.sizes.split(",") if s.strip()]
    os.makedirs(args.dir, exist_ok=True)

    started = datetime.datetime.now(datetime.timezone.utc)
    lmp_version = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "lammps"],
                                 capture_output=True, text=True).stdout
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo")
                if l.startswith("model name")), platform.processor())
    print(f"side-by-side with LAMMPS {lmp_version} on {os.cpu_count()} x {cpu}, "
          f"started {started:%Y-%m-%d %H:%M} UTC, load average {os.getloadavg()[0]:.1f}",
          flush=True)
    if args.cost_ratio:
        if len(set(sizes)) < 2:
            sys.exit("side_by_side: --cost-ratio needs two sizes, e.g. --sizes 10k,1.2M")
        rows, text = cost_ratio(args, sizes)
        write_results(args, "cost_ratio", started, cpu, text, {"rows": rows},
                      f"Cost per particle-step, 1 thread, {args.repeats} rounds")
        return
    check = None if args.skip_check else physics_check(args)

    scenes = ([("gas", 10000)] if args.gas_timing else []) + [("bed", n) for n in sizes]
    for kind, n in scenes:
        prepare(args, kind, n)
    print(f"\n== timing: median of {args.repeats}, stepping only ==", flush=True)
    rows = timing(args, scenes)
    write_results(args, "side_by_side", started, cpu, table(rows),
                  {"lammps": lmp_version, "check": check, "repeats": args.repeats,
                   "close_margin": args.close_margin, "rows": rows},
                  f"Side by side with LAMMPS {lmp_version}, median of {args.repeats}, ours "
                  f"with performance.close_margin {args.close_margin:g}")


if __name__ == "__main__":
    main()
