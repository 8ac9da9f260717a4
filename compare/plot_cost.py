#!/usr/bin/python3
"""Error versus cost plots from blockstep-compare's summary.json.

One PNG per scene: the scene's error (max joint separation, or a stack's
top-box drift) and, where there are contacts, the settled penetration (the
last second's mean deepest contact) against the median solve time per
frame, log-log. Quickstep's
iterations x sub-steps grid is drawn as one line per iteration count
through its sub-step counts, blockstep's sub-step settings as one line:
a setting below and left of another is better at no more cost.

Usage: plot_cost.py RESULTS_DIR   (reads RESULTS_DIR/summary.json and
writes RESULTS_DIR/cost_<scene>.png)
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display
import matplotlib.pyplot as plt  # noqa: E402

FLOOR = 1e-6  # m: errors below are drawn at the floor (log axes)


def series(runs):
    """Lines to draw: (label, [runs in cost order])."""
    lines = {}
    for r in runs:
        if r["stopped_because"]:
            continue
        if r["kind"] == "quickstep":
            key = "quickstep %d it" % r["iterations"]
        elif r["kind"] == "blockstep":
            key = "blockstep" if r["stepper"] == "blockstep" else "blockstep sub-steps"
        elif r["kind"] in ("pbd", "xpbd"):
            key = r["kind"].upper() + " (particles)"
        else:
            key = "dWorldStep"
        lines.setdefault(key, []).append(r)
    for key in lines:
        lines[key].sort(key=lambda r: r["median_solve_ms"])
    return sorted(lines.items())


def plot_scene(scene, runs, out_dir):
    contacts = any(r["max_penetration_m"] > 0 for r in runs)
    fields = ("error_m", "last_second_penetration_m") if contacts else ("error_m",)
    fig, axes = plt.subplots(1, len(fields), figsize=(5.5 * len(fields), 4.5), squeeze=False)
    axes = axes[0]
    for label, rs in series(runs):
        x = [r["median_solve_ms"] for r in rs]
        style = ("o-" if label.startswith("quickstep")
                 else "^--" if "particles" in label else "s-")
        for ax, field in zip(axes, fields):
            y = [max(r[field] * 1e3, FLOOR * 1e3) for r in rs]
            ax.plot(x, y, style, label=label)
            for r, xi, yi in zip(rs, x, y):
                ax.annotate(r["stepper"].split(":")[-1], (xi, yi), fontsize=6,
                            textcoords="offset points", xytext=(3, 3))
    error_is = runs[0]["error_is"]
    for ax, title in zip(axes, (error_is, "settled penetration (last second)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("median solve time per frame (ms)")
        ax.set_ylabel("mm")
        ax.set_title("%s: %s" % (scene, title))
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(out_dir, "cost_%s.png" % scene)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: plot_cost.py RESULTS_DIR")
    out_dir = sys.argv[1]
    path = os.path.join(out_dir, "summary.json")
    try:
        with open(path) as f:
            runs = json.load(f)
    except (OSError, ValueError) as e:
        sys.exit("plot_cost.py: cannot read %s: %s" % (path, e))
    scenes = {}
    for r in runs:
        scenes.setdefault(r["scene"], []).append(r)
    for scene, rs in scenes.items():
        print("plot_cost.py: wrote", plot_scene(scene, rs, out_dir))


if __name__ == "__main__":
    main()
