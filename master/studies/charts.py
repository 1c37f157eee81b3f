"""Charts and report of a study (called by study.py; docs/studies.md).

Error of a variant against the reference run, for the signals the study lists:
  raw:      sqrt(mean((v - r)^2)) / sqrt(mean(r^2)) over all signals and the variant's macro
            time points (the reference interpolated linearly onto them),
  filtered: the same after a centred moving average over `filter_seconds` (default 0.25 s)
            of both series, the load trend an engineer reads; the DEM's contact noise is
            not reproducible from run to run and dominates the raw error.
"""
import os
import textwrap

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ensemble import smooth  # noqa: E402  (the one moving average of the studies)


def overlap(run):
    """Largest and median per-step deepest overlap over the smaller radius, from a DEM
    participant's diagnostics (docs/dem_service.md), or None."""
    with h5py.File(run["h5"], "r") as f:
        for p in f.get("participants", {}):
            d = f"participants/{p}/diagnostics/max_overlap_ratio"
            if d in f:
                v = f[d][:]
                return float(np.nanmax(v)), float(np.nanmedian(v))
    return None


def read(run, signals):
    with h5py.File(run["h5"], "r") as f:
        t = f["time"][:]
        out = {}
        for s in signals:
            if s["path"] not in f:
                raise SystemExit(f"study: {run['h5']} has no dataset {s['path']}")
            out[s["path"]] = np.asarray(f[s["path"]][:], dtype=float).reshape(len(t), -1)[:, s.get("column", 0)]
        wall = float(np.sum(f["timing/step_wall"][:])) if "timing/step_wall" in f else run["wall_seconds"]
    return t, out, wall


def errors(ref, var, signals, seconds):
    tr, yr, _ = ref
    tv, yv, _ = var
    num = num_f = den = den_f = 0.0
    for s in signals:
        p = s["path"]
        r = np.interp(tv, tr, yr[p])
        rf = np.interp(tv, tr, smooth(tr, yr[p], seconds))
        vf = smooth(tv, yv[p], seconds)
        num += np.sum((yv[p] - r) ** 2)
        den += np.sum(r ** 2)
        num_f += np.sum((vf - rf) ** 2)
        den_f += np.sum(rf ** 2)
    return np.sqrt(num / den) if den > 0 else float("nan"), np.sqrt(num_f / den_f) if den_f > 0 else float("nan")


def make(study, runs, out_dir):
    signals = study["signals"]
    seconds = float(study.get("filter_seconds", 0.25))
    ok = [r for r in runs if r["exit_code"] == 0]
    data = {r["name"]: read(r, signals) for r in ok}
    ref = next((r for r in ok if r.get("reference")), None)
    for r in ok:
        r["wall_from_h5"] = data[r["name"]][2]
        ov = overlap(r)
        if ov is not None:
            r["max_overlap_ratio"], r["median_overlap_ratio"] = ov
        if ref is not None and r is not ref:
            r["error_raw"], r["error_filtered"] = errors(data[ref["name"]], data[r["name"]], signals, seconds)

    # Forces over time, one panel per signal, one curve per run (like the paper's Figs. 7, 8).
    n = len(signals)
    cols = 2 if n > 1 else 1
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(6.5 * cols, 3.2 * rows), squeeze=False, sharex=True)
    for k, s in enumerate(signals):
        ax = axes[k // cols][k % cols]
        for r in ok:
            t, y, _ = data[r["name"]]
            style = dict(lw=0.8, color="k", ls="--") if r.get("reference") else dict(lw=0.9)
            label = r["label"]
            if r.get("median_overlap_ratio", 0) > 0.2:  # flagged, not hidden: dotted and named
                style["ls"] = ":"
                label += f" (overlaps {r['median_overlap_ratio']:.1f} r: outside the contact model)"
            ax.plot(t, y[s["path"]] * float(s.get("scale", 1.0)), label=label, **style)
        ax.set_title(s["label"], fontsize=10)
        ax.grid(alpha=0.3)
        if k // cols == rows - 1:
            ax.set_xlabel("time [s]")
    axes[0][0].legend(fontsize=8)
    refused = [r for r in runs if "refused" in r]
    if refused:
        text = "\n".join(textwrap.fill(f"not plotted: {r['label']}: {r['refused']}", 190) for r in refused)
        fig.text(0.01, 0.005, text, fontsize=6.5, va="bottom", color="firebrick")
    fig.suptitle(f"{study['name']}: " + study.get("description", ""), fontsize=11)
    fig.tight_layout(rect=(0, 0.03 + 0.025 * text.count("\n") if refused else 0, 1, 0.96))
    forces_png = os.path.join(out_dir, "forces.png")
    fig.savefig(forces_png, dpi=120)
    plt.close(fig)

    # Work-precision: error against the reference versus wall time.
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    pts = [r for r in ok if "error_raw" in r]
    series = [("error_raw", "o", "raw")]
    if seconds > 0:
        series.append(("error_filtered", "s", f"{seconds:g} s moving average"))
    for key, marker, name in series:
        xs = [r["wall_from_h5"] for r in pts]
        ys = [100 * r[key] for r in pts]
        ax.plot(xs, ys, marker=marker, ls="none", label=name)
        for r, x, y in zip(pts, xs, ys):
            ax.annotate(r["label"], (x, y), fontsize=7, xytext=(4, 3), textcoords="offset points")
    if ref is not None:
        ax.axvline(ref["wall_from_h5"], color="k", ls="--", lw=0.8, label=f"reference: {ref['label']}")
    if any(r.get("error_raw", 0) > 0 for r in pts):
        ax.set_xscale("log")
        ax.set_yscale("log")
    else:
        ax.text(0.5, 0.5, "no successful reference run: nothing to compare", transform=ax.transAxes,
                ha="center", color="firebrick")
    ax.set_xlabel("wall time of the run [s]")
    ax.set_ylabel("error against the reference [%]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(f"{study['name']}: work-precision", fontsize=11)
    fig.tight_layout()
    wp_png = os.path.join(out_dir, "work_precision.png")
    fig.savefig(wp_png, dpi=120)
    plt.close(fig)

    # Report.
    lines = [f"# Study {study['name']}", "", study.get("description", ""), "",
             f"Error: RMS difference from the reference over {', '.join(s['label'] for s in signals)} at the "
             f"variant's macro time points, relative to the reference's RMS; filtered: after a {seconds:g} s "
             "moving average of both.", "",
             "Overlap: the deepest contact overlap of each macro step over the smaller radius (DEM "
             "diagnostics), largest and median over the run; beyond about 0.2 the linear contact "
             "model is outside its range (grains sink into each other) and the forces are not soil's.", "",
             "| run | exit | wall [s] | raw error [%] | filtered error [%] | overlap / r: max, median | note |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in runs:
        note = r.get("refused", r.get("failed", "reference" if r.get("reference") else ""))
        ov = ""
        if "max_overlap_ratio" in r:
            ov = f"{r['max_overlap_ratio']:.2f}, {r['median_overlap_ratio']:.2f}"
            if r["median_overlap_ratio"] > 0.2:
                note = (note + "; " if note else "") + "overlaps beyond the contact model's range"
        raw = f"{100 * r['error_raw']:.2f}" if "error_raw" in r else ""
        filt = f"{100 * r['error_filtered']:.2f}" if "error_filtered" in r else ""
        wall = f"{r.get('wall_from_h5', r['wall_seconds']):.1f}"
        lines.append(f"| {r['label']} | {r['exit_code']} | {wall} | {raw} | {filt} | {ov} | {note} |")
    lines += ["", f"Charts: {os.path.basename(forces_png)}, {os.path.basename(wp_png)}", ""]
    with open(os.path.join(out_dir, "report.md"), "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))
