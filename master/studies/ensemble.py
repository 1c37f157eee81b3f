"""Ensembles for studies in a chaotic scene (docs/studies.md, "Ensembles").

Every variant of a study with an `ensemble` section runs as N members that differ only by a
physically negligible perturbation (a seeded shift of the DEM's particle positions, a drawn
initial state). The statistics here separate a variant's real effect from the scene's
run-to-run scatter:

* per signal and time, the ensemble mean and standard deviation (after the study's moving
  average, on a common time grid);
* the distance of a variant's ensemble mean from the reference's ensemble mean,
      d = sqrt( sum_{signals, t} (mean_v - mean_r)^2 / sum_{signals, t} mean_r^2 ),
  with a 95 % bootstrap interval (members resampled within each ensemble), the level that
  scatter alone gives it (floor = sqrt(sum (s_v^2/n_v + s_r^2/n_r) / sum mean_r^2)), and a
  permutation test: how often a split of the pooled members into two groups of the same sizes
  lies as far apart as the observed one. p < alpha: "significant", else "within scatter";
* scalar outcomes (peak, mean, impulse over a phase, the final value, the time a signal first
  falls below a threshold) per member, their mean and spread per variant, and the difference
  from the reference with a Welch 95 % interval.
"""
import itertools
import math
import os

import numpy as np

# Two-sided 95 % quantiles of Student's t (df = 1..30); beyond 30 interpolated towards 1.96.
T975 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042]

ENSEMBLE_KEYS = {"members", "jobs", "perturb", "bus", "base_port", "window", "grid_step", "alpha",
                 "bootstrap"}
PERTURB_KEYS = {"key", "keys", "value", "seed", "normal"}
OUTCOME_KEYS = {"name", "path", "column", "stat", "from", "to", "scale", "threshold"}
STATS = {"max", "min", "mean", "integral", "final", "first_below", "first_above"}


class StudyError(Exception):
    """A study file that cannot run; the message names the key and the fix."""


def t975(df):
    if not (df >= 1):
        return float("nan")
    if df <= 30:
        i = int(math.floor(df))
        lo = T975[i - 1]
        hi = T975[min(i, 29)]
        return lo + (hi - lo) * (df - i)
    return 1.96 + (2.042 - 1.96) * 30.0 / df


def validate(study, where):
    """Checks the ensemble and outcomes sections; raises StudyError naming the key."""
    e = study["ensemble"]
    if not isinstance(e, dict):
        raise StudyError(f"{where}: ensemble must be a map with members and perturb (docs/studies.md)")
    unknown = set(e) - ENSEMBLE_KEYS
    if unknown:
        raise StudyError(f"{where}: ensemble: unknown key(s) {sorted(unknown)} (allowed: {sorted(ENSEMBLE_KEYS)})")
    n = e.get("members")
    if not isinstance(n, int) or isinstance(n, bool) or n < 2:
        raise StudyError(f"{where}: ensemble.members must be an integer >= 2 (a spread needs two runs), got {n!r}")
    jobs = e.setdefault("jobs", os.cpu_count() or 1)
    if not isinstance(jobs, int) or jobs < 1:
        raise StudyError(f"{where}: ensemble.jobs must be an integer >= 1, got {jobs!r}")
    perturb = e.get("perturb")
    if not isinstance(perturb, list) or not perturb:
        raise StudyError(f"{where}: ensemble.perturb must be a list of perturbations, e.g. "
                         "[{key: participants.soil.parameters.particles.perturb.seed, seed: 1}]")
    varying = False
    for k, p in enumerate(perturb):
        at = f"{where}: ensemble.perturb[{k}]"
        if not isinstance(p, dict):
            raise StudyError(f"{at}: must be a map with key (or keys) and one of value, seed, normal")
        unknown = set(p) - PERTURB_KEYS
        if unknown:
            raise StudyError(f"{at}: unknown key(s) {sorted(unknown)} (allowed: {sorted(PERTURB_KEYS)})")
        keys = p.get("keys", [p["key"]] if "key" in p else None)
        if not keys or not all(isinstance(x, str) and x for x in keys):
            raise StudyError(f"{at}: give key: <dotted config key> or keys: [list of them]")
        p["keys"] = keys
        kinds = [x for x in ("value", "normal") if x in p]
        if len(kinds) > 1:
            raise StudyError(f"{at}: give one of value, normal (with seed), or seed alone")
        if "normal" in p:
            nrm = p["normal"]
            if (not isinstance(nrm, dict) or set(nrm) != {"mean", "sigma"}
                    or not all(isinstance(nrm[x], (int, float)) for x in nrm) or not nrm["sigma"] > 0):
                raise StudyError(f"{at}: normal must be {{mean: number, sigma: number > 0}}")
            p.setdefault("seed", 0)
        if "seed" in p and (not isinstance(p["seed"], int) or isinstance(p["seed"], bool) or p["seed"] < 0):
            raise StudyError(f"{at}: seed must be an integer >= 0, got {p['seed']!r}")
        if "value" not in p and "seed" not in p:
            raise StudyError(f"{at}: give value (the same for every member), seed (member i gets "
                             "seed + i) or normal: {mean, sigma} (member i draws with seed + i)")
        varying = varying or "value" not in p
    if not varying:
        raise StudyError(f"{where}: ensemble.perturb: every entry is a fixed value, so all members "
                         "would be the same run; add one with seed or normal")
    for key in ("alpha",):
        if key in e and not (isinstance(e[key], float) and 0 < e[key] < 0.5):
            raise StudyError(f"{where}: ensemble.alpha must be a number in (0, 0.5), e.g. 0.05")
    if "window" in e:
        w = e["window"]
        if (not isinstance(w, list) or len(w) != 2 or not all(isinstance(x, (int, float)) for x in w)
                or not w[0] < w[1]):
            raise StudyError(f"{where}: ensemble.window must be [from, to] in seconds with from < to")
    if "grid_step" in e and not (isinstance(e["grid_step"], (int, float)) and e["grid_step"] > 0):
        raise StudyError(f"{where}: ensemble.grid_step must be a time > 0 s")
    for k, o in enumerate(study.get("outcomes", [])):
        at = f"{where}: outcomes[{k}]"
        if not isinstance(o, dict):
            raise StudyError(f"{at}: must be a map with name, path and stat")
        unknown = set(o) - OUTCOME_KEYS
        if unknown:
            raise StudyError(f"{at}: unknown key(s) {sorted(unknown)} (allowed: {sorted(OUTCOME_KEYS)})")
        for key in ("name", "path", "stat"):
            if key not in o:
                raise StudyError(f"{at}: '{key}' is missing")
        if o["stat"] not in STATS:
            raise StudyError(f"{at}: stat '{o['stat']}' is not one of {sorted(STATS)}")
        if o["stat"] in ("first_below", "first_above") and not isinstance(o.get("threshold"), (int, float)):
            raise StudyError(f"{at}: stat {o['stat']} needs threshold: <number, in the signal's unit before scale>")


def member_overrides(ensemble, variant, i):
    """The dotted-key overrides that make member i of a variant (a variant's `seed` shifts
    every seed, so two variants with the same settings can still be independent ensembles)."""
    offset = int(variant.get("seed", 0))
    out = {}
    for p in ensemble["perturb"]:
        if "normal" in p:
            rng = np.random.default_rng(p["seed"] + offset + i)
            value = float(rng.normal(p["normal"]["mean"], p["normal"]["sigma"]))
        elif "value" in p:
            value = p["value"]
        else:
            value = p["seed"] + offset + i
        for key in p["keys"]:
            out[key] = value
    return out


def bus_url(ensemble, slot):
    template = ensemble.get("bus", "udpm://239.255.76.67:{port}?ttl=0")
    return template.replace("{port}", str(int(ensemble.get("base_port", 7800)) + slot))


# --- Statistics -------------------------------------------------------------------------

def smooth(t, y, seconds):
    """Centred moving average over `seconds` (edges padded with the end values). Samples at
    uneven times (an adaptive macro step) are averaged over time, not over a count of samples:
    interpolated linearly onto an even grid at their shortest step, averaged, and read back at
    their own times."""
    if len(t) < 3 or seconds <= 0:
        return y
    steps = np.diff(t)
    dt = (t[-1] - t[0]) / (len(t) - 1)
    if steps.min() > 0 and steps.max() - steps.min() > 1e-9 * dt:
        h = float(steps.min())
        even = np.linspace(t[0], t[-1], int(round((t[-1] - t[0]) / h)) + 1)
        return np.interp(t, even, smooth(even, np.interp(even, t, y), seconds))
    n = max(1, int(round(seconds / dt)))
    kernel = np.ones(n) / n
    pad = np.pad(y, (n // 2, n - 1 - n // 2), mode="edge")
    return np.convolve(pad, kernel, mode="valid")


def finite(t, y):
    """The samples with a finite value (a power has none at t_start, for example)."""
    ok = np.isfinite(y)
    return (t, y) if ok.all() else (t[ok], y[ok])


def on_grid(members, paths, grid, seconds):
    """members: list of (t, {path: y}); returns array [member, signal, time]: each series
    smoothed on its own (finite) time points, then interpolated linearly onto the grid."""
    out = np.empty((len(members), len(paths), len(grid)))
    for m, (t, ys) in enumerate(members):
        for s, p in enumerate(paths):
            tt, yy = finite(t, ys[p])
            out[m, s] = np.interp(grid, tt, smooth(tt, yy, seconds))
    return out


def _distance(a, b, den):
    return math.sqrt(float(np.sum((a.mean(axis=0) - b.mean(axis=0)) ** 2)) / den)


def compare(X, R, alpha=0.05, bootstrap=2000, seed=12345):
    """X, R: [member, signal, time] of a variant and the reference (each signal already
    scaled to comparable units by the caller). Returns the distance of the ensemble means
    relative to the reference mean's RMS, its bootstrap interval, the scatter floor, the
    single-run scatter of each ensemble, the permutation p-value and the verdict."""
    nv, nr = X.shape[0], R.shape[0]
    mr = R.mean(axis=0)
    den = float(np.sum(mr ** 2))
    if den <= 0:
        raise StudyError("the reference ensemble's mean is zero everywhere: nothing to compare against")
    d = _distance(X, R, den)
    var_x = X.var(axis=0, ddof=1)
    var_r = R.var(axis=0, ddof=1)
    floor = math.sqrt(float(np.sum(var_x / nv + var_r / nr)) / den)
    rng = np.random.default_rng(seed)
    boots = np.empty(bootstrap)
    for b in range(bootstrap):
        boots[b] = _distance(X[rng.integers(0, nv, nv)], R[rng.integers(0, nr, nr)], den)
    lo, hi = np.percentile(boots, [2.5, 97.5])
    # Permutation test: every split of the pooled members when there are few, else a sample.
    pool = np.concatenate([X, R])
    n = nv + nr
    splits = math.comb(n, nv)
    count = total = 0
    if splits <= 20000:
        for chosen in itertools.combinations(range(n), nv):
            mask = np.zeros(n, bool)
            mask[list(chosen)] = True
            total += 1
            count += _distance(pool[mask], pool[~mask], den) >= d * (1 - 1e-12)
    else:
        for _ in range(5000):
            perm = rng.permutation(n)
            total += 1
            count += _distance(pool[perm[:nv]], pool[perm[nv:]], den) >= d * (1 - 1e-12)
        count += 1  # the observed split
        total += 1
    p = count / total
    return {
        "distance": d,
        "distance_ci": [float(lo), float(hi)],
        "excess": math.sqrt(max(0.0, d * d - floor * floor)),
        "floor": floor,
        "scatter_variant": math.sqrt(float(np.sum(var_x)) / den),
        "scatter_reference": math.sqrt(float(np.sum(var_r)) / den),
        "p_value": p,
        "min_p_value": (2 if nv == nr and splits <= 20000 else 1) / total,
        "verdict": "significant" if p < alpha else "within scatter",
    }


def outcome(t, y, o):
    """One scalar outcome of one member's (smoothed, finite) series."""
    t0 = float(o.get("from", t[0]))
    t1 = float(o.get("to", t[-1]))
    sel = (t >= t0 - 1e-12) & (t <= t1 + 1e-12)
    if not np.any(sel):
        return float("nan")
    tt, yy = t[sel], y[sel]
    stat = o["stat"]
    if stat == "max":
        return float(np.max(yy))
    if stat == "min":
        return float(np.min(yy))
    if stat == "mean":
        return float(np.trapz(yy, tt) / (tt[-1] - tt[0])) if len(tt) > 1 else float(yy[0])
    if stat == "integral":
        return float(np.trapz(yy, tt))
    if stat == "final":
        return float(yy[-1])
    hits = np.nonzero(yy < o["threshold"] if stat == "first_below" else yy > o["threshold"])[0]
    return float(tt[hits[0]]) if len(hits) else float("nan")


def welch(values, ref_values):
    """Difference of means with a Welch 95 % interval; None when either side has < 2 values."""
    a = np.asarray([v for v in values if np.isfinite(v)])
    b = np.asarray([v for v in ref_values if np.isfinite(v)])
    if len(a) < 2 or len(b) < 2:
        return None
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    diff = float(a.mean() - b.mean())
    se = math.sqrt(va + vb)
    if se == 0:
        return {"difference": diff, "ci": [diff, diff], "significant": diff != 0}
    df = (va + vb) ** 2 / ((va ** 2 / (len(a) - 1) if len(a) > 1 else 0) + (vb ** 2 / (len(b) - 1)))
    h = t975(df) * se
    return {"difference": diff, "ci": [diff - h, diff + h], "significant": not (diff - h <= 0 <= diff + h)}
