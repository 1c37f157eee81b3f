#!/usr/bin/python3
"""How the cost of the DEM's domain decomposition grows with ranks (docs/mpi.md, "How the cost
grows with ranks"): ghost (halo) grains per rank, bytes and messages per step, for the settled
beds of the LAMMPS side-by-side (bench/lammps, bench/common/tiled_bed.hpp) at 1, 2, 4, ... 64
ranks, decomposed into slabs and into the best 2-D and 3-D grids.

    /usr/bin/python3 bench/mpi/halo_model.py [--sizes 150k,600k] [--ranks 1,2,4,...,64]
        [--scene-dir results/bench_lammps] [--bandwidth 1.25e9] [--latency 20e-6]
        [--core-ns 95] [--ghost-bytes 80] [--markdown]

The model (every grain of radius r, skin s, the bed a box Lx x Ly x H of uniform number
density n = N / (Lx Ly H)):
  * a rank owns a box of the bed; cuts at equal counts are equal widths at uniform density;
  * its ghosts are the grains within the communication cutoff c = 2 r + s of its box that other
    ranks own: n times the volume of (its box grown by c on every side that has a neighbour,
    clipped to the bed) minus its own box (faces, edges and corners: the full shell);
  * forward communication every step sends each ghost's x, v and angular velocity (9 doubles)
    and its id (8 bytes): 80 bytes per ghost (--ghost-bytes: an engine that sends the ids only
    when the ghost lists change sends 72); a rank sends about what it receives;
  * messages per step per rank: "staged" exchanges one dimension after another (LAMMPS's
    scheme; edge and corner ghosts ride along), 2 per cut dimension, more when a subdomain is
    thinner than c; "direct" sends to every rank whose box touches its grown box;
  * an estimate of the communication's share of a step: bytes / bandwidth + messages x latency
    against (N / P) x core-ns per particle-step on one core per rank (docs/performance.md: 93-97
    core-ns at 150k-600k, 1 thread). It ignores the duplicated work on ghost pairs, the
    migration at neighbour-list rebuilds and load imbalance; it is a bound on the halo, not a
    prediction of speed-up.
With --scene-dir holding a bed's checkpoint (bed_N.h5, made by bench/lammps/side_by_side.sh),
the ghosts are also counted among the real grains, with cuts at equal counts ("counted").
"""
import argparse
import itertools
import math
import os
import sys

# The side-by-side beds (bench/common/anchor.hpp, tiled_bed.hpp): radius, skin, tiles of a
# settled 10k bed.
R = 0.005                 # m, kR
SKIN = 0.5 * R            # kSkin * kR
TILE = 10000
# Height of the settled 10k tile (and of every bed tiled from it): the top grain's centre,
# ztop - 20 r of results/bench_lammps/bed_150000.box (0.34130 m) as side_by_side.cpp writes it.
BED_HEIGHT = 0.34129516698421047 - 20 * R
GHOST_BYTES = 9 * 8 + 8   # x, v, u as doubles, the id


def tile_side(r=R):
    return math.sqrt(TILE / 40.0) * 2 * r * 1.15 + 2 * r


def tiling(n):
    k = max(1, n // TILE)
    nx = int(math.sqrt(k))
    while k % nx:
        nx -= 1
    return nx, k // nx


def parse_size(s):
    s = s.strip().lower()
    mult = {"k": 1000, "m": 1000000}.get(s[-1:], 1)
    try:
        v = float(s[:-1] if s[-1:] in "km" else s) * mult
    except ValueError:
        sys.exit(f"halo_model: size '{s}': expected e.g. 150k, 600k or 1.2M")
    n = int(round(v))
    if n < TILE or n % TILE:
        sys.exit(f"halo_model: size {s}: the beds are multiples of {TILE} grains (tiles of the 10k bed)")
    return n


class Bed:
    def __init__(self, n, height=BED_HEIGHT):
        tx, ty = tiling(n)
        self.n = n
        self.L = (tx * tile_side(), ty * tile_side(), height)
        self.density = n / (self.L[0] * self.L[1] * self.L[2])
        self.cutoff = 2 * R + SKIN


def rank_boxes(L, grid):
    """Equal-width cuts: per dimension the list of (lo, hi)."""
    return [[(L[d] * i / grid[d], L[d] * (i + 1) / grid[d]) for i in range(grid[d])] for d in range(3)]


def model(bed, grid):
    """Per-rank ghost volume, staged and direct messages, for a Px x Py x Pz grid of equal boxes."""
    c = bed.cutoff
    cuts = rank_boxes(bed.L, grid)
    per_dim = []  # per dimension, per index: (own width, grown width, lower hops, upper hops)
    for d in range(3):
        rows = []
        w = bed.L[d] / grid[d]
        for i, (lo, hi) in enumerate(cuts[d]):
            glo, ghi = max(0.0, lo - c), min(bed.L[d], hi + c)
            # neighbours within c below and above (more than one when w < c)
            below = min(i, math.ceil(c / w)) if i > 0 else 0
            above = min(grid[d] - 1 - i, math.ceil(c / w)) if i < grid[d] - 1 else 0
            rows.append((hi - lo, ghi - glo, below, above))
        per_dim.append(rows)
    ghosts, staged, direct = [], [], []
    for idx in itertools.product(*(range(g) for g in grid)):
        rows = [per_dim[d][idx[d]] for d in range(3)]
        own = math.prod(r[0] for r in rows)
        grown = math.prod(r[1] for r in rows)
        ghosts.append(bed.density * (grown - own))
        staged.append(sum(r[2] + r[3] for r in rows))
        direct.append(math.prod(1 + r[2] + r[3] for r in rows) - 1)
    return ghosts, staged, direct


def grids(p, dims):
    """Every Px x Py x Pz = p with Pz = 1 unless dims == 3 (dims 1: slabs along y)."""
    if dims == 1:
        return [(1, p, 1)]
    out = []
    for px in range(1, p + 1):
        if p % px:
            continue
        for py in range(1, p // px + 1):
            if (p // px) % py:
                continue
            pz = p // px // py
            if dims == 2 and pz != 1:
                continue
            out.append((px, py, pz))
    return out


def best_grid(bed, p, dims):
    return min(grids(p, dims), key=lambda g: (max(model(bed, g)[0]), sum(model(bed, g)[0])))


def counted(x, L, grid, c):
    """Ghosts per rank among the real grains x (N x 3), cuts at equal counts per dimension."""
    import numpy as np
    edges = []
    for d in range(3):
        q = np.quantile(x[:, d], np.linspace(0, 1, grid[d] + 1)) if grid[d] > 1 else np.array([-np.inf, np.inf])
        q[0], q[-1] = -np.inf, np.inf
        edges.append(q)
    out = []
    for idx in itertools.product(*(range(g) for g in grid)):
        inside = np.ones(len(x), bool)
        grown = np.ones(len(x), bool)
        for d in range(3):
            lo, hi = edges[d][idx[d]], edges[d][idx[d] + 1]
            inside &= (x[:, d] >= lo) & (x[:, d] < hi)
            grown &= (x[:, d] >= lo - c) & (x[:, d] < hi + c)
        out.append(int((grown & ~inside).sum()))
    return out


def load_positions(scene_dir, n):
    if not scene_dir:
        return None
    path = os.path.join(scene_dir, f"bed_{n}.h5")
    if not os.path.exists(path):
        return None
    import h5py
    import numpy as np
    with h5py.File(path, "r") as f:
        x = np.asarray(f["x"][:])
    if x.shape != (n, 3):
        sys.exit(f"halo_model: {path}: x has shape {x.shape}, expected ({n}, 3)")
    return x


def rows_for(bed, ranks, args, x):
    rows = []
    for p in ranks:
        for dims, label in ((1, "slabs"), (2, "2-D grid"), (3, "3-D grid")):
            if p == 1 and dims > 1:
                continue
            g = best_grid(bed, p, dims)
            ghosts, staged, direct = model(bed, g)
            owned = bed.n / p
            gmax, gmean = max(ghosts), sum(ghosts) / p
            bytes_max = gmax * args.ghost_bytes
            comm = bytes_max / args.bandwidth + max(staged) * args.latency
            compute = owned * args.core_ns * 1e-9
            row = {
                "P": p, "decomposition": label if p > 1 else "one rank",
                "grid": "x".join(str(v) for v in g), "owned": owned,
                "ghost_mean": gmean, "ghost_max": gmax, "halo_owned": gmax / owned,
                "bytes_max": bytes_max, "msg_staged": max(staged), "msg_direct": max(direct),
                "comm_share": comm / (comm + compute),
            }
            if x is not None:
                cnt = counted(x, bed.L, g, bed.cutoff)
                row["counted_mean"], row["counted_max"] = sum(cnt) / p, max(cnt)
            rows.append(row)
    return rows


def fmt_bytes(b):
    return f"{b / 1e6:.2f} MB" if b >= 1e6 else f"{b / 1e3:.0f} kB"


def print_table(bed, rows, markdown, have_counts):
    head = ["P", "decomposition", "grid", "owned", "ghosts mean", "ghosts max"]
    if have_counts:
        head += ["counted mean", "counted max"]
    head += ["max halo/owned", "bytes/step (max rank)", "msgs staged", "msgs direct", "comm share (est.)"]
    lines = []
    for r in rows:
        cells = [str(r["P"]), r["decomposition"], r["grid"], f"{r['owned']:.0f}", f"{r['ghost_mean']:.0f}",
                 f"{r['ghost_max']:.0f}"]
        if have_counts:
            cells += [f"{r['counted_mean']:.0f}", f"{r['counted_max']:.0f}"]
        cells += [f"{r['halo_owned']:.3f}", fmt_bytes(r["bytes_max"]), str(r["msg_staged"]), str(r["msg_direct"]),
                  f"{100 * r['comm_share']:.1f} %"]
        lines.append(cells)
    Lx, Ly, H = bed.L
    title = (f"{bed.n // 1000}k bed: {Lx:.3f} x {Ly:.3f} m, height {H:.3f} m, r = {R} m, cutoff 2r + skin = "
             f"{bed.cutoff:.4f} m, {bed.density:.4g} grains/m^3")
    if markdown:
        print(f"\n{title}\n")
        print("| " + " | ".join(head) + " |")
        print("|" + "|".join(" --- " for _ in head) + "|")
        for cells in lines:
            print("| " + " | ".join(cells) + " |")
    else:
        widths = [max(len(h), *(len(c[i]) for c in lines)) for i, h in enumerate(head)]
        print(f"\n{title}")
        print("  ".join(h.rjust(w) for h, w in zip(head, widths)))
        for cells in lines:
            print("  ".join(c.rjust(w) for c, w in zip(cells, widths)))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="150k,600k", help="beds, multiples of 10k (default 150k,600k)")
    p.add_argument("--ranks", default="1,2,4,8,16,32,64", help="rank counts (default 1,2,4,...,64)")
    p.add_argument("--scene-dir", default="results/bench_lammps",
                   help="where bench/lammps/side_by_side.sh keeps its beds; bed_N.h5 there adds counted ghosts")
    p.add_argument("--bandwidth", type=float, default=1.25e9, help="bytes/s per rank (default 10 GbE, 1.25e9)")
    p.add_argument("--latency", type=float, default=20e-6, help="s per message (default 20e-6)")
    p.add_argument("--core-ns", type=float, default=95.0,
                   help="core-ns per particle-step on one core (default 95, docs/performance.md)")
    p.add_argument("--ghost-bytes", type=float, default=GHOST_BYTES,
                   help=f"bytes per ghost per step (default {GHOST_BYTES}: x, v, u and the id)")
    p.add_argument("--markdown", action="store_true", help="print Markdown tables")
    args = p.parse_args()
    try:
        ranks = [int(v) for v in args.ranks.split(",") if v.strip()]
    except ValueError:
        sys.exit(f"halo_model: --ranks {args.ranks}: expected whole numbers, e.g. 1,2,4")
    if not ranks or min(ranks) < 1:
        sys.exit(f"halo_model: --ranks {args.ranks}: every count must be 1 or more")
    for name in ("bandwidth", "latency", "core_ns", "ghost_bytes"):
        if not getattr(args, name) > 0:
            sys.exit(f"halo_model: --{name.replace('_', '-')} must be positive")
    for n in (parse_size(s) for s in args.sizes.split(",") if s.strip()):
        bed = Bed(n)
        x = load_positions(args.scene_dir, n)
        rows = rows_for(bed, ranks, args, x)
        print_table(bed, rows, args.markdown, x is not None)
        if x is None and args.scene_dir:
            print(f"(no {args.scene_dir}/bed_{n}.h5: model only; bench/lammps/side_by_side.sh --sizes "
                  f"{n // 1000}k makes it)")
    print(f"\nghost = grain within 2r + skin of a rank's box owned by another rank; {args.ghost_bytes:g} B per ghost "
          f"per step; comm share = (bytes / {args.bandwidth:.3g} B/s + staged msgs x "
          f"{args.latency:.3g} s) against N/P x {args.core_ns:g} core-ns, one core per rank")


if __name__ == "__main__":
    main()
