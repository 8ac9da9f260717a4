#!/usr/bin/python3
"""How solve time and memory grow with the scene (Debian's matplotlib).

Runs blockstep-compare once per scene size and stepper, each in a process
of its own (so each peak resident size is that run's alone), and writes

  DIR/scaling.csv  scene, size, bodies, stepper, median solve ms a frame,
                   solve us a frame per body, peak resident kB, and kB per
                   body added since the scene's next smaller size
  DIR/scaling.png  solve time per body and memory per added body against
                   the body count, one line per scene and stepper

and prints the same as a table, with each size's time per body as a
multiple of the scene's smallest size measured. The sizes are the
runner's --size: cloth cells per side, the pile's layers of 100 shapes.
The peak resident size is the runner process's (ODE's world, the runner's
recording and blockstep's mirror), as it writes it to DIR/process.json
(VmHWM); its growth from one size to the next, per body added, leaves out
what every run holds (libraries, thread pools: about 8 MB).

Usage: scaling.py [--runner PATH] [--out DIR] [--frames N]
                  [--cloth 32,64,128] [--pile 1,10,100]
                  [--stepper quickstep:20 --stepper blockstep ...]
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")  # no display
import matplotlib.pyplot as plt  # noqa: E402

DEFAULT_RUNNER = os.path.join(os.path.dirname(__file__), "..", "..", "build", "compare",
                              "blockstep-compare")
COLUMNS = ["scene", "size", "bodies", "stepper", "solve_ms", "solve_us_per_body",
           "peak_rss_kb", "rss_kb_per_added_body"]


def sizes(text):
    try:
        values = [int(v) for v in text.split(",") if v]
    except ValueError:
        raise argparse.ArgumentTypeError("expected whole numbers separated by commas: " + text)
    if any(v < 1 or v > 256 for v in values):
        raise argparse.ArgumentTypeError("sizes are 1 to 256: " + text)
    return values


def run_one(runner, scene, size, stepper, frames):
    """One run in its own process: (summary of the run, bodies, peak kB)."""
    with tempfile.TemporaryDirectory() as out:
        command = [runner, "--scene", scene, "--size", str(size), "--stepper", stepper,
                   "--frames", str(frames), "--jobs", "1", "--out", out]
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        if done.returncode != 0:
            sys.exit("scaling.py: %s failed (exit %d): %s" %
                     (" ".join(command), done.returncode, done.stderr.decode(errors="replace")))
        with open(os.path.join(out, "summary.json")) as f:
            runs = json.load(f)
        scene_files = [n for n in os.listdir(out) if n.startswith("scene_") and n.endswith(".json")]
        if len(runs) != 1 or len(scene_files) != 1:
            sys.exit("scaling.py: expected one run and one scene file in %s's output" % scene)
        with open(os.path.join(out, scene_files[0])) as f:
            bodies = len(json.load(f)["bodies"])
        with open(os.path.join(out, "process.json")) as f:
            peak_kb = json.load(f)["peak_resident_kb"]
        return runs[0], bodies, peak_kb


def measure(args):
    rows = []
    for scene, scene_sizes in (("cloth", args.cloth), ("pile", args.pile)):
        for size in scene_sizes:
            for stepper in args.stepper:
                run, bodies, peak_kb = run_one(args.runner, scene, size, stepper, args.frames)
                if run["stopped_because"]:
                    print("%s size %d, %s: %s" % (scene, size, stepper, run["stopped_because"]))
                solve_ms = run["median_solve_ms"]
                rows.append({
                    "scene": scene, "size": size, "bodies": bodies, "stepper": stepper,
                    "solve_ms": solve_ms,
                    "solve_us_per_body": 1e3 * solve_ms / max(bodies, 1),
                    "peak_rss_kb": peak_kb, "rss_kb_per_added_body": "",
                })
    add_memory_growth(rows)
    return rows


def add_memory_growth(rows):
    """Each run's peak growth over the next smaller size's, per body added."""
    by_line = {}
    for r in rows:
        by_line.setdefault((r["scene"], r["stepper"]), []).append(r)
    for points in by_line.values():
        points.sort(key=lambda r: r["bodies"])
        for smaller, r in zip(points, points[1:]):
            added = r["bodies"] - smaller["bodies"]
            if added > 0:
                r["rss_kb_per_added_body"] = (r["peak_rss_kb"] - smaller["peak_rss_kb"]) / added


def print_table(rows):
    smallest = {}
    for r in rows:
        key = (r["scene"], r["stepper"])
        if key not in smallest or r["bodies"] < smallest[key]["bodies"]:
            smallest[key] = r
    print("%-6s %5s %7s %-28s %10s %12s %10s %10s %16s" %
          ("scene", "size", "bodies", "stepper", "solve ms", "us / body", "x smallest",
           "peak MB", "kB / added body"))
    for r in rows:
        base = smallest[(r["scene"], r["stepper"])]["solve_us_per_body"]
        growth = r["rss_kb_per_added_body"]
        print("%-6s %5d %7d %-28s %10.4f %12.3f %10.2f %10.1f %16s" %
              (r["scene"], r["size"], r["bodies"], r["stepper"], r["solve_ms"],
               r["solve_us_per_body"], r["solve_us_per_body"] / base if base > 0 else 0.0,
               r["peak_rss_kb"] / 1024.0, "%.2f" % growth if growth != "" else "-"))


def plot(rows, path):
    fig, (time_ax, memory_ax) = plt.subplots(1, 2, figsize=(11, 4.5))
    lines = {}
    for r in rows:
        lines.setdefault((r["scene"], r["stepper"]), []).append(r)
    for (scene, stepper), points in sorted(lines.items()):
        points.sort(key=lambda r: r["bodies"])
        bodies = [r["bodies"] for r in points]
        label = "%s, %s" % (scene, stepper)
        time_ax.plot(bodies, [r["solve_us_per_body"] for r in points], "o-", label=label)
        grown = [r for r in points if r["rss_kb_per_added_body"] != ""]
        memory_ax.plot([r["bodies"] for r in grown],
                       [max(r["rss_kb_per_added_body"], 1e-3) for r in grown], "o-", label=label)
    for ax, title in ((time_ax, "solve time per body (us a frame)"),
                      (memory_ax, "peak resident size per added body (kB)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("bodies")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    time_ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runner", default=DEFAULT_RUNNER)
    parser.add_argument("--out", default="scaling")
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument("--cloth", type=sizes, default=[32, 64, 128])
    parser.add_argument("--pile", type=sizes, default=[1, 10, 100])
    parser.add_argument("--stepper", action="append")
    args = parser.parse_args()
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    if not os.access(args.runner, os.X_OK):
        parser.error("no runner at %s (build first, or pass --runner)" % args.runner)
    args.stepper = args.stepper or ["quickstep:20", "blockstep"]
    os.makedirs(args.out, exist_ok=True)
    rows = measure(args)
    with open(os.path.join(args.out, "scaling.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, os.path.join(args.out, "scaling.png"))
    print_table(rows)


if __name__ == "__main__":
    main()
