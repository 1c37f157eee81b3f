#!/usr/bin/python3
"""Tool side-by-side benchmark against LIGGGHTS (driven by tool_side_by_side.sh; method in
docs/performance.md, "Tool scene against LIGGGHTS").

1. Scene, once (cached in --dir): the settled 150k bed of the LAMMPS side-by-side (made by
   `dem_side_by_side prepare` if --bed-dir lacks it), the bucket STL and the bed minus the
   spheres the bucket overlaps at t = 0, for both codes (`dem_tool_side_by_side prepare`).
2. Timing: 1 thread vs 1 rank and 2 threads vs 2 ranks, N repeats, ours and LIGGGHTS back to
   back. Only the stepping is timed: both step --warmup times (the bucket already moves), then
   ours times --steps steps with its own clock and LIGGGHTS reports the `Loop time` of its
   second `run`. Prints simulated time, wall time, real-time factor (wall / simulated),
   particle-steps/s, the ratio ours/LIGGGHTS (median of the per-repeat ratios) and the CPU
   share each run got.
3. Force check: the force on the bucket in the direction of motion (y), averaged over blocks of
   --block steps of the timed window (ours: every step summed in the program; LIGGGHTS:
   `fix ave/time 1 B B` on the force of `fix mesh/surface/stress`). Compares the window mean
   and the peak block mean of both codes in every repeat; fails (exit 1) beyond the stated
   tolerances.
"""
import argparse
import datetime
import json
import os
import platform
import re
import resource
import statistics
import subprocess
import sys
import time

# Tolerances of the force check (see docs/performance.md for why these values): the bed's
# response to the bucket is chaotic in detail and the two codes resolve mesh edges and corners
# differently, so only means over 1 ms blocks and over the window are compared.
MEAN_TOL = 0.10  # relative, mean of F_y over the timed window
PEAK_TOL = 0.15  # relative, largest |block mean of F_y|

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMP_NUM_THREADS": "1"}


def read_kv(path):
    kv = {}
    with open(path) as f:
        for line in f:
            k, v = line.split()
            kv[k] = v
    return kv


def g(x):
    return repr(float(x))


def liggghts_input(args, box, policy):
    """LIGGGHTS input for the tool scene: same spheres, contact law, walls, mesh, motion, dt,
    skin. Atom type 1: the spheres; type 2: the walls and the bucket."""
    kn = float(box["stiffness"])
    kt = kn * 2.0 / 7.0
    m = float(box["mass"])
    eta_pp = m / 2 * float(box["gamma_n"])  # absolute dashpot, m* = m/2 between two spheres
    eta_pw = m * float(box["gamma_n"])      # m* = m against a wall or the bucket
    mu = float(box["friction"])

    def pairs(pp, pw):  # peratomtypepair 2: 11 12 21 22 (22, wall-wall, is never used)
        return f"2 {g(pp)} {g(pw)} {g(pw)} {g(pw)}"

    law = "model hooke/stiffness tangential history"
    keys = "absolute_damping on limitForce off tangential_damping on"
    sx, sy = float(box["sx"]), float(box["sy"])
    lines = [
        "units si",
        "atom_style granular",
        "atom_modify map array",
        "boundary f f f",
        "newton off",
        "communicate single vel yes",
        f"read_data {os.path.join(args.dir, 'tool_bed.data')}",
        f"neighbor {g(box['skin'])} bin",
        ("neigh_modify every 1 delay 0 check yes" if policy == 0
         else f"neigh_modify every {policy} delay 0 check no"),
        f"timestep {g(box['dt'])}",
        f"fix k_n all property/global kn peratomtypepair {pairs(kn, kn)}",
        f"fix k_t all property/global kt peratomtypepair {pairs(kt, kt)}",
        f"fix eta_n all property/global gamman_abs peratomtypepair {pairs(eta_pp, eta_pw)}",
        f"fix eta_t all property/global gammat_abs peratomtypepair "
        f"{pairs(eta_pp / 2, eta_pw / 2)}",
        f"fix mu all property/global coefficientFriction peratomtypepair {pairs(mu, mu)}",
        f"pair_style gran {law} {keys}",
        "pair_coeff * *",
        f"fix bucket all mesh/surface/stress file {os.path.join(args.dir, 'bucket.stl')} type 2"
        f" reference_point {g(box['ref_x'])} {g(box['ref_y'])} {g(box['ref_z'])}",
        f"fix wbucket all wall/gran {law} mesh n_meshes 1 meshes bucket {keys}",
        f"fix wx0 all wall/gran {law} primitive type 2 xplane 0.0 {keys}",
        f"fix wx1 all wall/gran {law} primitive type 2 xplane {g(sx)} {keys}",
        f"fix wy0 all wall/gran {law} primitive type 2 yplane 0.0 {keys}",
        f"fix wy1 all wall/gran {law} primitive type 2 yplane {g(sy)} {keys}",
        f"fix wz0 all wall/gran {law} primitive type 2 zplane 0.0 {keys}",
        f"fix move all move/mesh mesh bucket linear {g(box['vx'])} {g(box['vy'])} "
        f"{g(box['vz'])}",
        "fix integrate all nve",  # translation only: no rotation, like ours
        "fix gravity all gravity 9.81 vector 0 0 -1",
        "thermo_style custom step atoms",
        "thermo 1000000",
        f"run {args.warmup}",
        f"fix force all ave/time 1 {args.block} {args.block} f_bucket[1] f_bucket[2] "
        f"f_bucket[3] file {os.path.join(args.dir, 'liggghts_force.txt')}",
        f"run {args.steps}",
    ]
    return "\n".join(lines) + "\n"


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_liggghts(args, box, ranks):
    name = f"tool_{ranks}"
    path = os.path.join(args.dir, name + ".in")
    with open(path, "w") as f:
        f.write(liggghts_input(args, box, args.interval))
    log_path = os.path.join(args.dir, name + ".log")
    cmd = ["mpirun", "-np", str(ranks), "--bind-to", "core", "liggghts", "-in", path, "-log",
           log_path, "-screen", os.path.join(args.dir, name + ".screen"), "-nocite"]
    # (-screen none crashes this LIGGGHTS: the STL reader prints to the screen unchecked)
    cpu0, t0 = children_cpu(), time.monotonic()
    res = subprocess.run(cmd, env=dict(os.environ, **MPI_ENV), capture_output=True, text=True)
    whole_wall, whole_cpu = time.monotonic() - t0, children_cpu() - cpu0
    log = open(log_path).read() if os.path.exists(log_path) else ""
    if res.returncode != 0 or "ERROR" in log:
        sys.exit(f"tool_side_by_side: LIGGGHTS failed ({' '.join(cmd)}):\n{res.stderr[-2000:]}"
                 f"\n{log[-2000:]}")
    loops = re.findall(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+)"
                       r" atoms", log)
    seconds, procs, nsteps, atoms = loops[-1]
    if int(procs) != ranks or int(nsteps) != args.steps:
        sys.exit(f"tool_side_by_side: unexpected LIGGGHTS loop line {loops[-1]}")
    builds = re.findall(r"Neighbor list builds = (\d+)", log)
    phases = {k.lower(): float(v) for k, v in
              re.findall(r"(Pair|Neigh|Comm|Outpt|Other) +time \(%\) = ([0-9.eE+-]+)", log)[-5:]}
    forces = []
    with open(os.path.join(args.dir, "liggghts_force.txt")) as f:
        for line in f:
            if not line.startswith("#") and line.strip():
                step, fx, fy, fz = line.split()
                forces.append((int(step) * float(box["dt"]), float(fx), float(fy), float(fz)))
    return {"seconds": float(seconds), "atoms": int(atoms),
            "rebuilds": int(builds[-1]) if builds else -1,
            # whole process (setup included; no per-run figure in this LIGGGHTS's log)
            "cpu_share": whole_cpu / (whole_wall * ranks), "forces": forces, "phases": phases}


def run_ours(args, threads):
    cmd = [args.dem, "run", "--dir", args.dir, "--threads", str(threads), "--interval",
           str(args.interval), "--steps", str(args.steps), "--warmup", str(args.warmup),
           "--block", str(args.block)]
    res = subprocess.run(cmd, capture_output=True, text=True,
                         env=dict(os.environ, OMP_NUM_THREADS=str(threads)))
    if res.returncode != 0:
        sys.exit(f"tool_side_by_side: {' '.join(cmd)} failed:\n{res.stderr[-2000:]}")
    lines = res.stdout.splitlines()
    f = lines[0].split()
    forces = [tuple(map(float, l.split()[1:])) for l in lines[1:] if l.startswith("F ")]
    ph = next(l.split()[1:] for l in lines if l.startswith("phases"))
    phases = {ph[i]: float(ph[i + 1]) for i in range(0, len(ph), 2) if ph[i] != "output"}
    return {"seconds": float(f[f.index("seconds") + 1]), "atoms": int(f[f.index("n") + 1]),
            "rebuilds": int(f[f.index("rebuilds") + 1]),
            "cpu_share": float(f[f.index("cpu_share") + 1]), "forces": forces, "phases": phases}


def force_stats(forces):
    fy = [f[2] for f in forces]
    fh = [(f[1] ** 2 + f[2] ** 2) ** 0.5 for f in forces]
    return {"mean_fy": statistics.fmean(fy), "peak_fy": max(fy, key=abs),
            "mean_fh": statistics.fmean(fh), "blocks": len(fy)}


def prepare(args):
    if os.path.exists(os.path.join(args.dir, "tool_bed.box")):
        return
    stem = os.path.join(args.bed_dir, "bed_150000")
    if not os.path.exists(stem + ".box"):
        print(f"preparing the settled 150k bed in {args.bed_dir} (about 2 min) ...", flush=True)
        res = subprocess.run([args.bed_tool, "prepare", "--kind", "bed", "--n", "150000",
                              "--dir", args.bed_dir], stderr=subprocess.PIPE, text=True)
        if res.returncode != 0:
            sys.exit(f"tool_side_by_side: bed preparation failed:\n{res.stderr[-2000:]}")
    res = subprocess.run([args.dem, "prepare", "--bed", stem, "--dir", args.dir],
                         stderr=subprocess.PIPE, text=True)
    if res.returncode != 0:
        sys.exit(f"tool_side_by_side: tool scene preparation failed:\n{res.stderr[-2000:]}")
    print(res.stderr.strip(), flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", default="1,2", help="thread counts = MPI rank counts")
    p.add_argument("--steps", type=int, default=1000, help="timed steps (multiple of --block)")
    p.add_argument("--warmup", type=int, default=100, help="untimed steps before the clock")
    p.add_argument("--block", type=int, default=100, help="steps per force block mean")
    p.add_argument("--interval", type=int, default=0,
                   help="0: rebuild when needed (skin guard / check yes); N: every N steps")
    p.add_argument("--dir", default="results/bench_liggghts")
    p.add_argument("--bed-dir", default="results/bench_lammps",
                   help="where the LAMMPS side-by-side keeps (or will make) bed_150000.*")
    p.add_argument("--dem", required=True, help="path of dem_tool_side_by_side")
    p.add_argument("--bed-tool", required=True, help="path of dem_side_by_side")
    args = p.parse_args()
    if args.steps % args.block or args.warmup % args.block:
        sys.exit("tool_side_by_side: --steps and --warmup must be multiples of --block (the "
                 "force blocks of both codes end at the same steps)")
    args.threads = [int(t) for t in args.threads.split(",")]
    os.makedirs(args.dir, exist_ok=True)

    started = datetime.datetime.now(datetime.timezone.utc)
    version = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "liggghts"],
                             capture_output=True, text=True).stdout
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo")
                if l.startswith("model name")), platform.processor())
    load0 = os.getloadavg()
    print(f"tool side-by-side with LIGGGHTS {version} on {os.cpu_count()} x {cpu}, started "
          f"{started:%Y-%m-%d %H:%M} UTC, load average {load0[0]:.2f} {load0[1]:.2f} "
          f"{load0[2]:.2f}", flush=True)
    prepare(args)
    box = read_kv(os.path.join(args.dir, "tool_bed.box"))
    n = int(box["n"])
    dt = float(box["dt"])
    sim = args.steps * dt
    print(f"scene: {n} spheres, bucket {box['triangles']} triangles at {float(box['vy']):g} m/s;"
          f" {args.warmup} warm-up steps, then {args.steps} timed steps ({sim:g} s simulated), "
          f"{'rebuild when needed' if args.interval == 0 else f'rebuild every {args.interval}'}"
          f", median of {args.repeats}", flush=True)

    rows, checks, failed = [], [], False
    for threads in args.threads:
        runs = {"ours": [], "liggghts": []}
        for rep in range(args.repeats):
            a = run_ours(args, threads)
            b = run_liggghts(args, box, threads)
            if a["atoms"] != n or b["atoms"] != n:
                sys.exit(f"tool_side_by_side: particles lost ({a['atoms']} / {b['atoms']} of {n})")
            runs["ours"].append(a)
            runs["liggghts"].append(b)
            fa, fb = force_stats(a["forces"]), force_stats(b["forces"])
            if fa["blocks"] != fb["blocks"] or any(
                    abs(x[0] - y[0]) > 1e-9 for x, y in zip(a["forces"], b["forces"])):
                sys.exit(f"tool_side_by_side: {fa['blocks']} force blocks from ours, "
                         f"{fb['blocks']} from LIGGGHTS")
            d_mean = abs(fa["mean_fy"] - fb["mean_fy"]) / abs(fb["mean_fy"])
            d_peak = abs(fa["peak_fy"] - fb["peak_fy"]) / abs(fb["peak_fy"])
            ok = d_mean <= MEAN_TOL and d_peak <= PEAK_TOL
            failed |= not ok
            checks.append({"threads": threads, "repeat": rep, "ours": fa, "liggghts": fb,
                           "d_mean": d_mean, "d_peak": d_peak, "ok": ok,
                           "blocks_ours": a["forces"], "blocks_liggghts": b["forces"]})
            print(f"  {threads} vs {threads} #{rep + 1}: ours {a['seconds']:.2f} s "
                  f"({a['rebuilds']} broad phases, CPU share {a['cpu_share']:.2f}), LIGGGHTS "
                  f"{b['seconds']:.2f} s ({b['rebuilds']} neighbour builds, CPU share of the "
                  f"whole process {b['cpu_share']:.2f}), ratio {b['seconds'] / a['seconds']:.2f};"
                  f" F_y mean {fa['mean_fy']:.1f} / {fb['mean_fy']:.1f} N ({d_mean:.1%}), peak "
                  f"{fa['peak_fy']:.1f} / {fb['peak_fy']:.1f} N ({d_peak:.1%})"
                  f"{'' if ok else '  FORCE CHECK FAILED'}", flush=True)
        ratios = [b["seconds"] / a["seconds"] for a, b in zip(runs["ours"], runs["liggghts"])]
        row = {"threads": threads, "steps": args.steps, "simulated": sim, "n": n,
               "ratio": statistics.median(ratios), "ratios": ratios}
        for code in ("ours", "liggghts"):
            wall = statistics.median(r["seconds"] for r in runs[code])
            row[code] = {"wall": wall, "rtf": wall / sim, "rate": n * args.steps / wall,
                         "walls": [r["seconds"] for r in runs[code]],
                         "rebuilds": runs[code][-1]["rebuilds"],
                         "phases": runs[code][-1]["phases"],
                         "cpu_share": statistics.median(r["cpu_share"] for r in runs[code])}
        rows.append(row)

    ended = datetime.datetime.now(datetime.timezone.utc)
    load1 = os.getloadavg()
    table = ["| threads vs ranks | code | simulated [s] | wall [s] | real-time factor (wall / "
             "simulated) | particle-steps/s | ours/LIGGGHTS (speed) | rebuilds | CPU share |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        for code, name in (("ours", "ours"), ("liggghts", "LIGGGHTS")):
            c = r[code]
            table.append(f"| {r['threads']} vs {r['threads']} | {name} | {r['simulated']:g} | "
                         f"{c['wall']:.2f} | {c['rtf']:.0f} | {c['rate']:.3g} | "
                         + (f"**{r['ratio']:.2f}** ({', '.join(f'{x:.2f}' for x in r['ratios'])})"
                            if code == "ours" else "") +
                         f" | {c['rebuilds']} | {c['cpu_share']:.2f} |")
    phase_lines = []
    for r in rows:
        for code, name in (("ours", "ours"), ("liggghts", "LIGGGHTS")):
            ph = r[code]["phases"]
            total = sum(ph.values())
            phase_lines.append(f"* {r['threads']} vs {r['threads']}, {name}: " + ", ".join(
                f"{k} {v:.2f} s ({v / total:.0%})" for k, v in ph.items() if v > 0))
    force = ["| threads vs ranks | repeat | mean F_y ours [N] | LIGGGHTS [N] | difference | "
             "peak block F_y ours [N] | LIGGGHTS [N] | difference | mean horizontal magnitude "
             "ours / LIGGGHTS [N] |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for c in checks:
        force.append(f"| {c['threads']} vs {c['threads']} | {c['repeat'] + 1} | "
                     f"{c['ours']['mean_fy']:.1f} | {c['liggghts']['mean_fy']:.1f} | "
                     f"{c['d_mean']:.1%} | {c['ours']['peak_fy']:.1f} | "
                     f"{c['liggghts']['peak_fy']:.1f} | {c['d_peak']:.1%} | "
                     f"{c['ours']['mean_fh']:.1f} / {c['liggghts']['mean_fh']:.1f} |")
    blocks = ["| t [s] | F_y ours [N] | F_y LIGGGHTS [N] |", "| ---: | ---: | ---: |"]
    for (t, _, fy1, _), (_, _, fy2, _) in zip(checks[0]["blocks_ours"],
                                              checks[0]["blocks_liggghts"]):
        blocks.append(f"| {t:.4f} | {fy1:.1f} | {fy2:.1f} |")
    head = (f"Tool side by side with LIGGGHTS {version}, {os.cpu_count()} x {cpu}, "
            f"{started:%Y-%m-%d %H:%M}-{ended:%H:%M} UTC, median of {args.repeats}, load "
            f"average {load0[0]:.2f} at the start and {load1[0]:.2f} at the end")
    text = (head + "\n\n" + "\n".join(table) + "\n\nTime per phase in the timed steps "
            "(last repeat; ours: the engine's timer, mesh_contacts = walls and the bucket; "
            "LIGGGHTS: its log, Other = the fixes: walls, mesh, mesh motion, integration):\n\n"
            + "\n".join(phase_lines) + "\n\nForce on the bucket in the direction of "
            f"motion, block means of {args.block} steps (tolerance: window mean "
            f"{MEAN_TOL:.0%}, peak block {PEAK_TOL:.0%}):\n\n" + "\n".join(force) +
            f"\n\nBlock means of the first pair ({checks[0]['threads']} vs "
            f"{checks[0]['threads']}):\n\n" + "\n".join(blocks) + "\n")
    print("\n" + text)
    stamp = f"{started:%Y%m%d_%H%M}"
    with open(os.path.join(args.dir, f"tool_side_by_side_{stamp}.md"), "w") as f:
        f.write(text)
    with open(os.path.join(args.dir, f"tool_side_by_side_{stamp}.json"), "w") as f:
        json.dump({"started": started.isoformat(), "ended": ended.isoformat(), "cpu": cpu,
                   "load_average_start": load0, "load_average_end": load1,
                   "liggghts": version, "args": {k: v for k, v in vars(args).items()},
                   "rows": rows, "force_checks": checks}, f, indent=1)
    print(f"written to {args.dir}/tool_side_by_side_{stamp}.md and .json "
          f"({(ended - started).total_seconds() / 60:.1f} min)")
    if failed:
        print("tool_side_by_side: FAILED: the force on the bucket differs beyond the tolerance",
              file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
