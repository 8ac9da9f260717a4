#!/usr/bin/python3
"""The comparison's plots (Debian's matplotlib), from blockstep-compare's output.

Error versus cost, one PNG per scene (cost_<scene>.png): the scene's
error (max joint separation, or a stack's top-box drift) and, where there
are contacts, the settled penetration (the last second's mean deepest
contact) against the median solve time per frame, log-log. Quickstep's
iterations x sub-steps grid is drawn as one line per iteration count
through its sub-step counts, blockstep's sub-step settings as one line:
a setting below and left of another is better at no more cost.

Convergence from one saved state, one PNG per convergence_<scene>.csv
(convergence_<scene>.png): how far one step's velocities are from the
converged step's after n sweeps, for quickstep and blockstep's block,
row-by-row and island-block sweeps, and blockstep's residual per sweep.

Usage: plots.py RESULTS_DIR   (writes both kinds next to their inputs;
report.py calls the same functions)
"""
import csv
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


CONVERGENCE_COLUMNS = (
    ("quickstep_speed_error", "quickstep (SOR, shuffled rows)", "o-"),
    ("blockstep_speed_error", "blockstep: a block per joint", "s-"),
    ("blockstep_rows_speed_error", "blockstep: row by row", "v-"),
    ("blockstep_island_speed_error", "blockstep: island blocks", "D-"),
)


def read_convergence(path):
    """The convergence CSV as {column: [values]} (empty cells left out)."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError("%s has no rows" % path)
    table = {}
    for key in rows[0]:
        table[key] = [float(r[key]) if r[key] else None for r in rows]
    return table


def plot_convergence(scene, path, out_dir):
    """convergence_<scene>.png from convergence_<scene>.csv."""
    table = read_convergence(path)
    sweeps = table["sweeps"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for key, label, style in CONVERGENCE_COLUMNS:
        y = [max(v, 1e-16) for v in table[key]]
        axes[0].plot(sweeps, y, style, label=label, markersize=3)
    for key, label in (("blockstep_residual_max", "largest row"),
                       ("blockstep_residual_rms", "RMS over rows")):
        pts = [(n, v) for n, v in zip(sweeps, table[key]) if v is not None]
        if pts:
            axes[1].plot([p[0] for p in pts], [max(p[1], 1e-16) for p in pts], "s-",
                         label=label, markersize=3)
    axes[0].set_title("%s: one step's velocity off the converged step's" % scene)
    axes[0].set_ylabel("largest body's speed difference (m/s)")
    axes[1].set_title("%s: blockstep's residual per sweep" % scene)
    axes[1].set_ylabel("m/s")
    for ax in axes:
        ax.set_yscale("log")
        ax.set_xlabel("sweeps (iterations) in the step")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    out = os.path.join(out_dir, "convergence_%s.png" % scene)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def read_summary(out_dir):
    """summary.json's runs grouped by scene, in the order they ran."""
    path = os.path.join(out_dir, "summary.json")
    with open(path) as f:
        runs = json.load(f)
    scenes = {}
    for r in runs:
        scenes.setdefault(r["scene"], []).append(r)
    return scenes


def convergence_files(out_dir):
    """[(scene, path)] of every convergence_<scene>.csv in out_dir."""
    found = []
    for name in sorted(os.listdir(out_dir)):
        if name.startswith("convergence_") and name.endswith(".csv"):
            found.append((name[len("convergence_"):-len(".csv")], os.path.join(out_dir, name)))
    return found


def plot_all(out_dir):
    """Every plot the folder's results allow; returns the PNG paths."""
    written = []
    if os.path.exists(os.path.join(out_dir, "summary.json")):
        for scene, rs in read_summary(out_dir).items():
            written.append(plot_scene(scene, rs, out_dir))
    for scene, path in convergence_files(out_dir):
        written.append(plot_convergence(scene, path, out_dir))
    return written


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: plots.py RESULTS_DIR")
    try:
        for path in plot_all(sys.argv[1]):
            print("plots.py: wrote", path)
    except (OSError, ValueError, KeyError) as e:
        sys.exit("plots.py: cannot read the results in %s: %s" % (sys.argv[1], e))


if __name__ == "__main__":
    main()
