#!/usr/bin/python3
"""mpi_halo_model_test: bench/mpi/halo_model.py against closed forms and against a count.

* slabs: an end rank's ghosts are n c Lx H, an interior rank's 2 n c Lx H (c = 2 r + skin);
* a grid's interior rank: the full shell n ((a + 2c)(b + 2c) H - a b H) for a 2-D grid;
* messages: 2 ranks exchange 1 message each; a 3x3 grid's centre rank 4 staged, 8 direct;
* slabs thinner than c reach past their neighbours (ghosts from 2 ranks a side);
* the model's ghost counts agree with a count among random grains filling the bed's box
  (within 3 % at the mean);
* bad input (a size that is no multiple of 10k, a rank count of 0) is refused by name.
"""
import importlib.util
import math
import subprocess
import sys

src = sys.argv[1]
spec = importlib.util.spec_from_file_location("halo_model", f"{src}/bench/mpi/halo_model.py")
hm = importlib.util.module_from_spec(spec)
spec.loader.exec_module(hm)

fails = []


def check(cond, what):
    print(("ok: " if cond else "FAIL: ") + what)
    if not cond:
        fails.append(what)


bed = hm.Bed(150000)
Lx, Ly, H = bed.L
n, c = bed.density, bed.cutoff
check(abs(c - 0.0125) < 1e-15, f"cutoff 2r + skin = 0.0125 m (got {c})")
check(abs(n * Lx * Ly * H - 150000) < 1e-6, "density x box volume = N")

ghosts, staged, direct = hm.model(bed, (1, 4, 1))
end, mid = n * c * Lx * H, 2 * n * c * Lx * H
check(abs(ghosts[0] - end) < 1e-9 * end and abs(ghosts[3] - end) < 1e-9 * end, f"end slabs: n c Lx H = {end:.1f}")
check(abs(ghosts[1] - mid) < 1e-9 * mid and abs(ghosts[2] - mid) < 1e-9 * mid, f"interior slabs: 2 n c Lx H = {mid:.1f}")
check(staged == [1, 2, 2, 1] and direct == [1, 2, 2, 1], f"slab messages 1,2,2,1 (got {staged}, {direct})")

ghosts, staged, direct = hm.model(bed, (3, 3, 1))
a, b = Lx / 3, Ly / 3
shell = n * ((a + 2 * c) * (b + 2 * c) * H - a * b * H)
check(abs(ghosts[4] - shell) < 1e-9 * shell, f"3x3 grid centre: full shell {shell:.1f} (got {ghosts[4]:.1f})")
check(staged[4] == 4 and direct[4] == 8, f"3x3 grid centre: 4 staged, 8 direct messages (got {staged[4]}, {direct[4]})")
corner = n * ((a + c) * (b + c) * H - a * b * H)
check(abs(ghosts[0] - corner) < 1e-9 * corner and staged[0] == 2 and direct[0] == 3, "3x3 grid corner: grown on two sides")

# 150k in 128 slabs along y: 7.5 mm thick, thinner than c = 12.5 mm: two neighbours a side.
ghosts, staged, direct = hm.model(bed, (1, 128, 1))
check(staged[64] == 4 and direct[64] == 4, f"slabs thinner than c: 4 messages (got {staged[64]}, {direct[64]})")
check(abs(ghosts[64] - mid) < 1e-9 * mid, "slabs thinner than c: still 2 n c Lx H ghosts")

# Against a count: uniform random grains at 4x the bed's density filling its box (the model
# scaled to that density; about 8000 ghosts at 2 ranks, a count's scatter under 1.2 %).
import numpy as np
rng = np.random.default_rng(7)
x = rng.uniform(0, 1, (4 * 150000, 3)) * np.array(bed.L)
lattice = hm.Bed(150000)
lattice.density = len(x) / (Lx * Ly * H)
for grid in [(1, 2, 1), (1, 8, 1), (2, 4, 1), (4, 4, 2)]:
    model = np.mean(hm.model(lattice, grid)[0])
    count = np.mean(hm.counted(x, bed.L, grid, c))
    check(abs(count / model - 1) < 0.03, f"grid {grid}: counted {count:.0f} vs model {model:.0f} ghosts (3 %)")

# The command line: a table for the defaults, refusals by name.
exe = [sys.executable, f"{src}/bench/mpi/halo_model.py", "--scene-dir", ""]
out = subprocess.run(exe + ["--sizes", "150k", "--ranks", "1,2"], capture_output=True, text=True)
check(out.returncode == 0 and "150k bed" in out.stdout and "1x2x1" in out.stdout, "a table for 150k at 1, 2 ranks")
bad = subprocess.run(exe + ["--sizes", "15k"], capture_output=True, text=True)
check(bad.returncode != 0 and "multiples of 10000" in bad.stderr, "size 15k refused by name")
bad = subprocess.run(exe + ["--ranks", "0,2"], capture_output=True, text=True)
check(bad.returncode != 0 and "every count must be 1 or more" in bad.stderr, "0 ranks refused by name")

print("mpi_halo_model_test: " + ("all checks passed" if not fails else f"{len(fails)} failed"))
sys.exit(1 if fails else 0)
