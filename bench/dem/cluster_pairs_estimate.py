#!/usr/bin/python3
"""How much work a cluster pair list would give the pair forces of a settled bed, against the
half list the engine screens today (docs/performance.md, "The screened stream").

A cluster pair kernel (as in molecular dynamics codes) groups particles in clusters of 4, lists
pairs of clusters with at least one particle pair within reach (r_i + r_j + skin), and computes
every one of the 16 particle pairs of a listed cluster pair in vector lanes, the partners loaded
as whole vectors. This counts, on a bed from `dem_side_by_side prepare` (positions and radii of
its HDF5 file):
  * candidates per particle in the half list (pairs within reach, each once), and the 4-lane
    groups the AVX2 kernel's screen takes for them (a row's candidates 4 at a time);
  * listed cluster pairs per cluster (each unordered pair once, a cluster with itself counted),
    for clusters made (a) of 4 consecutive particles in the engine's cell order (cells of
    2 r_max + skin, x fastest) and (b) as column codes do: columns in x-y of about 4 particles'
    volume a side, sorted by z in each column, cut in fours;
  * the lane pairs a 4 x 4 kernel computes per particle (16 per listed cluster pair) and the
    share of them that are candidates.
The exact test per listed cluster pair is the best case: a real list tests cluster bounding
boxes and lists more.

usage: cluster_pairs_estimate.py [BED.h5] [--skin S]
   default: results/bench_lammps/bed_150000.h5, skin 0.5 r_max (the bench's bed)
"""
import argparse
import sys

import h5py
import numpy as np
from scipy.spatial import cKDTree


def candidate_pairs(x, r, skin):
    tree = cKDTree(x)
    pairs = tree.query_pairs(2 * r.max() + skin, output_type="ndarray")
    d = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1)
    return pairs[d < r[pairs[:, 0]] + r[pairs[:, 1]] + skin]


def cluster_count(pairs, cluster_of):
    a, b = cluster_of[pairs[:, 0]], cluster_of[pairs[:, 1]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return len(np.unique(lo.astype(np.int64) * (cluster_of.max() + 1) + hi))


def cell_order(x, h):
    lo = x.min(axis=0)
    c = np.floor((x - lo) / h).astype(np.int64)
    n = c.max(axis=0) + 1
    key = (c[:, 2] * n[1] + c[:, 1]) * n[0] + c[:, 0]
    return np.argsort(key, kind="stable")


def column_order(x, side):
    lo = x.min(axis=0)
    c = np.floor((x[:, :2] - lo[:2]) / side).astype(np.int64)
    col = c[:, 1] * (c[:, 0].max() + 1) + c[:, 0]
    return np.lexsort((x[:, 2], col))  # by column, then z


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bed", nargs="?", default="results/bench_lammps/bed_150000.h5")
    ap.add_argument("--skin", type=float, default=None, help="absolute skin [m]; default 0.5 r_max")
    args = ap.parse_args()
    try:
        with h5py.File(args.bed, "r") as f:
            x = np.asarray(f["x"], dtype=float)
            r = np.asarray(f["radius"], dtype=float)
    except (OSError, KeyError) as e:
        sys.exit(f"cluster_pairs_estimate: cannot read x and radius from {args.bed}: {e} "
                 "(make the bed with: build/bin/dem_side_by_side prepare --kind bed --n 150000 "
                 "--dir results/bench_lammps)")
    n = len(x)
    if n < 4:
        sys.exit(f"cluster_pairs_estimate: {args.bed} holds {n} particles; a cluster needs 4")
    if args.skin is not None and not args.skin >= 0:
        sys.exit(f"cluster_pairs_estimate: --skin {args.skin}: give a distance of 0 m or more")
    skin = args.skin if args.skin is not None else 0.5 * r.max()
    pairs = candidate_pairs(x, r, skin)
    print(f"{args.bed}: {n} particles, r {r.min():.4g}-{r.max():.4g} m, skin {skin:.4g} m")
    # Today's screen: each row (the pairs of a particle with the later ones in cell order) in
    # groups of 4 candidates of that row.
    by_cell = cell_order(x, 2 * r.max() + skin)
    rank = np.empty(n, dtype=np.int64)
    rank[by_cell] = np.arange(n)
    rows = np.bincount(np.minimum(rank[pairs[:, 0]], rank[pairs[:, 1]]), minlength=n)
    groups = np.sum((rows + 3) // 4)
    print(f"candidates (half list): {len(pairs) / n:.2f} per particle, screened in "
          f"{groups / n:.2f} 4-lane groups per particle ({len(pairs) / groups:.2f} of 4 lanes filled)")
    volume_per_particle = np.prod(x.max(axis=0) - x.min(axis=0)) / n
    for name, order in (
            ("4 consecutive in cell order", by_cell),
            ("columns of 4 particles' volume, by z", column_order(x, (4 * volume_per_particle) ** (1 / 3)))):
        cluster_of = np.empty(n, dtype=np.int64)
        cluster_of[order] = np.arange(n) // 4
        nc = int(cluster_of.max()) + 1
        cp = cluster_count(pairs, cluster_of)
        lanes = 16 * cp / n
        print(f"{name}: {cp / nc:.1f} cluster pairs per cluster, {lanes:.1f} lane pairs per "
              f"particle ({lanes / 4:.1f} 4-lane groups), {100 * len(pairs) / (16 * cp):.0f} % "
              f"of them candidates")


if __name__ == "__main__":
    main()
