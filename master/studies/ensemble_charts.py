"""Statistics, charts and report of an ensemble study (called by study.py; docs/studies.md).

Writes in OUTPUT_DIR: forces.png (every signal's ensemble mean with a +-1 standard deviation
band per variant, the reference in black), work_precision.png (each variant's distance from the
reference with its 95 % interval over the CPU seconds of a member, filled when significant),
outcomes.png (scalar outcomes, mean and spread per variant), report.md and summary.json.
"""
import json
import os
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import ensemble as ens  # noqa: E402
import ensemble_run  # noqa: E402


def _mean_std(values):
    a = np.asarray([v for v in values if np.isfinite(v)], dtype=float)
    if len(a) == 0:
        return float("nan"), float("nan"), 0
    return float(a.mean()), float(a.std(ddof=1)) if len(a) > 1 else float("nan"), len(a)


def analyse(study, variants, metas):
    e = study["ensemble"]
    seconds = float(study.get("filter_seconds", 0.25))
    signals = study["signals"]
    outcomes = study.get("outcomes", [])
    keys = [(s["path"], int(s.get("column", 0))) for s in signals]
    okeys = [(o["path"], int(o.get("column", 0))) for o in outcomes]
    results = []
    data = {}
    for v in variants:
        ms = metas[v["name"]]
        ok = [m for m in ms if m is not None and m["exit_code"] == 0]
        r = {"label": v["label"], "name": v["name"], "reference": bool(v.get("reference")),
             "set": v["set"], "members_ok": len(ok), "members": len(ms),
             "missing": [i for i, m in enumerate(ms) if m is None],
             "failed": [i for i, m in enumerate(ms) if m is not None and m["exit_code"] not in (0, 2)]}
        refused = [m for m in ms if m is not None and m["exit_code"] == 2]
        if refused:
            r["refused"] = refused[0]["refused"]
        if ok:
            r["cpu_seconds"] = _mean_std([m["cpu_seconds"] for m in ok])[:2]
            r["wall_seconds"] = _mean_std([m["wall_seconds"] for m in ok])[:2]
            data[v["name"]] = [ensemble_run.read_member(m, keys + okeys) for m in ok]
        results.append(r)
    usable = [r for r in results if r["members_ok"] >= 2]
    if not usable:
        return results, None
    # The common grid: the window all members cover, at the coarsest of their time steps.
    runs = [d for r in usable for d in data[r["name"]]]
    w0 = max(float(t[0]) for t, _ in runs)
    w1 = min(float(t[-1]) for t, _ in runs)
    if "window" in e:
        w0, w1 = max(w0, float(e["window"][0])), min(w1, float(e["window"][1]))
    if not w1 > w0:
        raise ens.StudyError(f"the members share no time window to compare (from {w0} s to {w1} s)")
    step = float(e.get("grid_step", max(float(np.median(np.diff(t))) for t, _ in runs)))
    grid = np.arange(w0, w1 + 0.5 * step, step)
    grid = grid[grid <= w1 + 1e-12]
    scale = np.array([float(s.get("scale", 1.0)) for s in signals])
    arrays = {}
    for r in usable:
        members = [(t, {k: ys[k] for k in keys}) for t, ys in data[r["name"]]]
        arrays[r["name"]] = ens.on_grid(members, keys, grid, seconds) * scale[None, :, None]
        r["band_mean"] = arrays[r["name"]].mean(axis=0)
        r["band_std"] = arrays[r["name"]].std(axis=0, ddof=1)
        r["outcomes"] = {}
        for o, k in zip(outcomes, okeys):
            vals = []
            for t, ys in data[r["name"]]:
                tt, yy = ens.finite(t, ys[k])
                vals.append(ens.outcome(tt, ens.smooth(tt, yy, seconds), o) * float(o.get("scale", 1.0)))
            r["outcomes"][o["name"]] = vals
    ref = next((r for r in usable if r["reference"]), None)
    alpha = float(e.get("alpha", 0.05))
    if ref is not None:
        for r in usable:
            if r is ref:
                continue
            r["comparison"] = ens.compare(arrays[r["name"]], arrays[ref["name"]], alpha,
                                          int(e.get("bootstrap", 2000)))
            r["outcome_differences"] = {o["name"]: ens.welch(r["outcomes"][o["name"]], ref["outcomes"][o["name"]])
                                        for o in outcomes}
    return results, {"grid": grid, "window": [w0, w1], "step": step, "ref": ref, "alpha": alpha}


def make(study, variants, metas, out_dir):
    results, ctx = analyse(study, variants, metas)
    signals = study["signals"]
    outcomes = study.get("outcomes", [])
    seconds = float(study.get("filter_seconds", 0.25))
    n_members = study["ensemble"]["members"]
    usable = [r for r in results if "band_mean" in r]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    color = {}
    k = 0
    for r in usable:
        if r["reference"]:
            color[r["name"]] = "k"
        else:
            color[r["name"]] = colors[k % len(colors)]
            k += 1

    # Forces over time: bands of +-1 standard deviation.
    if ctx is not None:
        grid = ctx["grid"]
        n = len(signals)
        cols = 2 if n > 1 else 1
        rows = (n + cols - 1) // cols
        fig, axes = plt.subplots(rows, cols, figsize=(6.5 * cols, 3.3 * rows), squeeze=False, sharex=True)
        for s_i, s in enumerate(signals):
            ax = axes[s_i // cols][s_i % cols]
            for r in usable:
                m, sd = r["band_mean"][s_i], r["band_std"][s_i]
                c = color[r["name"]]
                ax.plot(grid, m, color=c, lw=1.0 if r["reference"] else 0.9,
                        ls="--" if r["reference"] else "-", label=f"{r['label']} ({r['members_ok']})")
                ax.fill_between(grid, m - sd, m + sd, color=c, alpha=0.12 if r["reference"] else 0.18, lw=0)
            ax.set_title(s["label"], fontsize=10)
            ax.grid(alpha=0.3)
            if s_i // cols == rows - 1:
                ax.set_xlabel("time [s]")
        axes[0][0].legend(fontsize=7)
        fig.suptitle(f"{study['name']}: ensemble mean and +-1 standard deviation (members in brackets"
                     + (f"; {seconds:g} s moving average" if seconds > 0 else "") + ")", fontsize=10)
        fig.tight_layout(rect=(0, 0, 1, 0.96))
        fig.savefig(os.path.join(out_dir, "forces.png"), dpi=120)
        plt.close(fig)

    # Speed against accuracy.
    pts = [r for r in usable if "comparison" in r]
    # Many variants: numbers at the points and a key beside the plot, or the labels overlap.
    many = len(pts) > 8
    fig, ax = plt.subplots(figsize=(11.5, 5.5) if many else (7, 4.8))
    for k, r in enumerate(pts, 1):
        c = r["comparison"]
        x, xs = r["cpu_seconds"]
        y = 100 * c["distance"]
        lo, hi = 100 * c["distance_ci"][0], 100 * c["distance_ci"][1]
        sig = c["verdict"] == "significant"
        xe = xs if np.isfinite(xs) else 0.0
        ax.errorbar([x], [y], xerr=[[xe], [xe]], yerr=[[max(0.0, y - lo)], [max(0.0, hi - y)]], fmt="o", ms=7, capsize=3,
                    color=color[r["name"]], mfc=color[r["name"]] if sig else "white")
        ax.annotate(str(k) if many else r["label"], (x, y), fontsize=7, xytext=(5, 4),
                    textcoords="offset points")
    ref = ctx["ref"] if ctx else None
    if ref is not None and pts:
        scat = 100 * pts[0]["comparison"]["scatter_reference"]
        ax.axhline(scat, color="0.4", ls="--", lw=0.8, label=f"one run's scatter ({scat:.2g} %)")
        ax.axvline(ref["cpu_seconds"][0], color="k", ls=":", lw=0.8, label=f"reference: {ref['label']}")
        ax.set_xscale("log")
        ax.plot([], [], "o", color="0.3", label="significant (filled)")
        ax.plot([], [], "o", color="0.3", mfc="white", label="within scatter (open)")
    else:
        ax.text(0.5, 0.5, "no reference ensemble with 2 or more members: nothing to compare",
                transform=ax.transAxes, ha="center", color="firebrick")
    ax.set_xlabel("cost of one member [CPU s, master and participants]")
    ax.set_ylabel("distance of ensemble means from the reference [%]")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title(f"{study['name']}: speed against accuracy (up to {n_members} members each; 95 % intervals)", fontsize=10)
    if many:
        key = "\n".join(f"{k}: {r['label']}" for k, r in enumerate(pts, 1))
        fig.text(0.63, 0.5, key, fontsize=7, va="center", ha="left")
        fig.tight_layout(rect=(0, 0, 0.62, 1))
    else:
        fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "work_precision.png"), dpi=120)
    plt.close(fig)

    # Scalar outcomes.
    if outcomes and usable:
        n = len(outcomes)
        cols = 2 if n > 1 else 1
        rows = (n + cols - 1) // cols
        fig, axes = plt.subplots(rows, cols, figsize=(6.5 * cols, 0.9 + 0.32 * len(usable) * rows + 1.2 * rows),
                                 squeeze=False)
        for o_i, o in enumerate(outcomes):
            ax = axes[o_i // cols][o_i % cols]
            for y_i, r in enumerate(usable):
                vals = np.asarray(r["outcomes"][o["name"]], float)
                m, sd, _ = _mean_std(vals)
                ax.plot(vals, np.full(len(vals), y_i), "|", color=color[r["name"]], ms=8, alpha=0.6)
                ax.errorbar([m], [y_i], xerr=[[sd if np.isfinite(sd) else 0], [sd if np.isfinite(sd) else 0]],
                            fmt="o", color=color[r["name"]], capsize=3, ms=5)
            ax.set_yticks(range(len(usable)))
            ax.set_yticklabels([r["label"] for r in usable], fontsize=7)
            ax.set_title(o["name"], fontsize=9)
            ax.grid(alpha=0.3)
        for j in range(n, rows * cols):
            axes[j // cols][j % cols].axis("off")
        fig.suptitle(f"{study['name']}: outcomes per member (|) and mean +-1 standard deviation", fontsize=10)
        fig.tight_layout(rect=(0, 0, 1, 0.95))
        fig.savefig(os.path.join(out_dir, "outcomes.png"), dpi=120)
        plt.close(fig)

    # Report.
    alpha = ctx["alpha"] if ctx else 0.05
    lines = [f"# Study {study['name']} (ensembles of {n_members} members)", "", study.get("description", ""), ""]
    if ctx:
        lines += [f"Compared on {ctx['window'][0]:g}-{ctx['window'][1]:g} s every {ctx['step']:g} s"
                  + (f", after a {seconds:g} s moving average" if seconds > 0 else "")
                  + f", over {', '.join(s['label'] for s in signals)}.", "",
                  "distance: RMS of the difference of the ensemble means over the RMS of the reference's mean; "
                  "interval: 95 % bootstrap; floor: what scatter alone gives the distance; one run's scatter: "
                  "RMS of the standard deviation over the RMS of the mean; p: permutation test; "
                  f"significant when p < {alpha:g}.", ""]
    lines += ["| variant | members | CPU s per member | wall s per member | distance [%] | 95 % interval [%] | floor [%] | one run's scatter [%] | p | verdict | note |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in results:
        cpu = f"{r['cpu_seconds'][0]:.1f} +- {r['cpu_seconds'][1]:.1f}" if "cpu_seconds" in r else ""
        wall = f"{r['wall_seconds'][0]:.1f}" if "wall_seconds" in r else ""
        note = []
        if r["reference"]:
            note.append("reference")
        if r.get("refused"):
            note.append("refused: " + r["refused"])
        if r["missing"]:
            note.append(f"not run yet: members {r['missing']}")
        if r["failed"]:
            note.append(f"failed: members {r['failed']}")
        c = r.get("comparison")
        if c:
            cells = [f"{100 * c['distance']:.2f}", f"{100 * c['distance_ci'][0]:.2f}-{100 * c['distance_ci'][1]:.2f}",
                     f"{100 * c['floor']:.2f}", f"{100 * c['scatter_variant']:.2f}", f"{c['p_value']:.3f}", c["verdict"]]
        else:
            scat = ""
            if r["reference"] and pts:
                scat = f"{100 * pts[0]['comparison']['scatter_reference']:.2f}"
            cells = ["", "", "", scat, "", ""]
        lines.append(f"| {r['label']} | {r['members_ok']}/{r['members']} | {cpu} | {wall} | " + " | ".join(cells)
                     + f" | {'; '.join(note)} |")
    if outcomes and usable:
        lines += ["", "Outcomes: mean +- standard deviation over the members; difference from the reference "
                  "with its Welch 95 % interval (* = the interval excludes 0).", ""]
        lines.append("| variant | " + " | ".join(o["name"] for o in outcomes) + " |")
        lines.append("| --- |" + " --- |" * len(outcomes))
        for r in usable:
            cells = []
            for o in outcomes:
                m, sd, n_ok = _mean_std(r["outcomes"][o["name"]])
                cell = f"{m:.4g} +- {sd:.2g}" if n_ok > 1 else (f"{m:.4g}" if n_ok else "n/a")
                diff = r.get("outcome_differences", {}).get(o["name"])
                if diff:
                    cell += (f"; {diff['difference']:+.3g} [{diff['ci'][0]:+.3g}, {diff['ci'][1]:+.3g}]"
                             + ("*" if diff["significant"] else ""))
                cells.append(cell)
            lines.append(f"| {r['label']} | " + " | ".join(cells) + " |")
    lines += ["", "Charts: forces.png, work_precision.png" + (", outcomes.png" if outcomes else ""), ""]
    with open(os.path.join(out_dir, "report.md"), "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))

    def clean(r):
        out = {k: v for k, v in r.items() if k not in ("band_mean", "band_std")}
        return out

    summary = {"study": study["name"], "ensemble": True, "members": n_members,
               "window": ctx["window"] if ctx else None, "variants": [clean(r) for r in results]}
    if ctx:
        summary["grid"] = ctx["grid"].tolist()
        summary["bands"] = {r["name"]: {"mean": r["band_mean"].tolist(), "std": r["band_std"].tolist()}
                            for r in usable}
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    return results
