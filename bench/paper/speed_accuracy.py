#!/usr/bin/python3
"""Speed against accuracy for paper-scene runs (bench/paper/paper_scene.sh --out DIR): for each
run its real-time factor over the whole maneuver (dem_run's loop times over simulated time) and
the change of its bucket force against the reference run (compare.py's filtered RMS measure),
printed as a table and drawn as a chart. Pass scatter runs (the reference setting with a
physically negligible change: --set particles.perturb.amplitude=4e-9 with its own seed; another
thread count no longer changes a bit) to draw the scene's own scatter: their mean is what the
"x scatter" column divides by, their range the band on the chart.

usage: speed_accuracy.py --reference DIR [--scatter DIR ...] LABEL=DIR ... [--out PNG]
"""
import argparse
import os
import re
import statistics
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402


def real_time_factor(folder, policy):
    wall = sim = 0.0
    for k, name in enumerate(compare.PHASES):
        log = os.path.join(folder, f"{policy}_{k + 1}_{name}.log")
        if not os.path.exists(log):
            sys.exit(f"speed_accuracy: {log} is missing; run bench/paper/paper_scene.sh --out "
                     f"{folder} --policies {policy} first")
        text = open(log).read()
        m = re.search(r"Loop time of ([0-9.]+) s for ([0-9]+) steps", text)
        d = re.search(r"run\.duration=([0-9.eE+-]+)", text)
        if not m or not d:
            sys.exit(f"speed_accuracy: {log} has no loop time or run.duration (did the run end?)")
        wall += float(m.group(1))
        sim += float(d.group(1))
    return wall / sim


def change(reference, other, policy, window):
    """Raw and filtered bucket force change over the whole maneuver."""
    _, _, raw, filt, _, _ = compare.compare_runs(reference, other, policy, window)[-1]
    return raw, filt


def main():
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", metavar="LABEL=DIR")
    p.add_argument("--reference", required=True)
    p.add_argument("--scatter", action="append", default=[])
    p.add_argument("--policy", default="needed")
    p.add_argument("--filter", type=float, default=0.02)
    p.add_argument("--out", default="results/paper_speed_accuracy.png")
    a = p.parse_args()
    runs = []
    for spec in a.runs:
        if "=" not in spec:
            sys.exit(f"speed_accuracy: '{spec}' is not LABEL=DIR")
        label, folder = spec.split("=", 1)
        runs.append((label, folder))
    ref_rtf = real_time_factor(a.reference, a.policy)
    print(f"reference {a.reference}: real-time factor {ref_rtf:.0f}")
    scatter = None
    members = []
    for folder in a.scatter:
        raw, filt = change(a.reference, folder, a.policy, a.filter)
        members.append((raw, filt))
        print(f"scatter {folder}: force change raw {100 * raw:.2f} %, filtered {100 * filt:.2f} %")
    if members:
        scatter = (sum(m[0] for m in members) / len(members),
                   sum(m[1] for m in members) / len(members))
        if len(members) > 1:
            print(f"scatter, mean of {len(members)}: raw {100 * scatter[0]:.2f} %, filtered "
                  f"{100 * scatter[1]:.2f} % (filtered {100 * min(m[1] for m in members):.2f}"
                  f"-{100 * max(m[1] for m in members):.2f} %)")
        if len(members) > 2:
            sd = statistics.stdev(m[1] for m in members)
            print(f"scatter, filtered: standard deviation {100 * sd:.2f} % over the "
                  f"{len(members)} members")
    widest = max((m[1] for m in members), default=0.0)
    print("| run | real-time factor | speed-up | force change raw | filtered | x scatter (filtered) "
          "| x largest member |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    rows = []
    for label, folder in runs:
        rtf = real_time_factor(folder, a.policy)
        raw, filt = change(a.reference, folder, a.policy, a.filter)
        ratio = f"{filt / scatter[1]:.1f}" if scatter and scatter[1] > 0 else "-"
        beyond = f"{filt / widest:.1f}" if widest > 0 else "-"
        print(f"| {label} | {rtf:.0f} | {ref_rtf / rtf:.2f} | {100 * raw:.2f} % | "
              f"{100 * filt:.2f} % | {ratio} | {beyond} |")
        rows.append((label, ref_rtf / rtf, 100 * filt))  # speed-up, filtered change in %
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("speed_accuracy: no matplotlib (apt-get install python3-matplotlib); no chart")
        return
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot([0] + [f for _, _, f in rows], [1] + [s for _, s, _ in rows], "o")
    ax.annotate("all active (reference)", (0, 1), textcoords="offset points", xytext=(5, 5))
    for label, s, f in rows:
        ax.annotate(label, (f, s), textcoords="offset points", xytext=(6, -3), ha="left",
                    fontsize=8)
    ax.set_xlim(left=0, right=1.3 * max([f for _, _, f in rows] + [100 * m[1] for m in members] + [1e-9]))
    if scatter:
        ax.axvline(100 * scatter[1], color="grey", linestyle="--",
                   label=f"scatter (mean of {len(members)} run{'s' if len(members) > 1 else ''})")
        if len(members) > 1:
            ax.axvspan(100 * min(m[1] for m in members), 100 * max(m[1] for m in members),
                       color="grey", alpha=0.15, label="scatter range")
        ax.legend()
    ax.set_xlabel(f"bucket force change, filtered {a.filter} s [%]")
    ax.set_ylabel("speed-up against all active")
    ax.set_title("paper scene: speed against accuracy")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
    fig.savefig(a.out, dpi=120)
    print(f"chart: {a.out}")


if __name__ == "__main__":
    main()
