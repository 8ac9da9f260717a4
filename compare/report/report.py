#!/usr/bin/python3
"""The comparison's HTML report, from what blockstep-compare --out wrote.

Usage: report.py RESULTS_DIR

Writes, into RESULTS_DIR, report.html (opens offline, from file://):
  - the summary table of every run, scene by scene, with solve time
    against quickstep 20's, joint error, penetration and drift, and what
    stopped a run;
  - where blockstep stands at equal cost: which quickstep settings some
    blockstep setting beats at no more solve time, and which none does;
  - the paper's own figures beside ours;
  - the error-versus-cost plots and the convergence plots (plots.py);
  - a side-by-side 3D replay of any two steppers' recorded runs
    (replay.js, with three.js from Debian's libjs-three copied next to the
    report), from replay_<scene>.js files written here.
"""
import base64
import html
import json
import math
import os
import shutil
import struct
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plots  # noqa: E402

THREE_JS = "/usr/share/javascript/three/three.min.js"  # Debian's libjs-three
HERE = os.path.dirname(os.path.abspath(__file__))
QUATERNION_SCALE = 32767

# The paper's own figures (its section 6), beside the same scene here.
PAPER_FIGURES = (
    ("ragdoll", "blockstep", "Fig. 1: a skeletal model of 5 rigid bodies, the solver 0.4 ms per frame", 0.4),
    ("cloth32", "blockstep", "Fig. 2: cloth of 32 x 32 rigid bodies, the constraint solve 111 ms per frame", 111.0),
    ("cloth32", "pbd:20", "Fig. 3: its position-based cloth of as many points, 1 ms per frame", 1.0),
    ("softcube", "blockstep", "Fig. 5: 125 rigid bodies and 300 constraints, 13 ms per time step", 13.0),
)


def mm(x):
    return "%.3f" % (x * 1e3)


def run_note(r):
    notes = []
    if r["exploded"]:
        notes.append("EXPLODED")
    if r["stopped_because"] and not r["exploded"]:
        notes.append(r["stopped_because"])
    if r.get("runaway_frames"):
        notes.append("runaway guard fired in %d frames" % r["runaway_frames"])
    if r.get("ode_stepped_frames"):
        notes.append("ODE stepped %d frames (unsupported)" % r["ode_stepped_frames"])
    if r.get("ode_messages"):
        notes.append("%d ODE messages" % r["ode_messages"])
    return "; ".join(notes)


def ran(r):
    return not r["stopped_because"]


def standing(runs, with_collision=False):
    """Per quickstep setting: the cheapest blockstep setting that beats it
    at no more solve time, or with with_collision no more solve and
    collision time (lower error, settled contact no deeper, 0.1 mm slack),
    or None; as blockstep-compare counts them."""
    def cost(r):
        return r["median_solve_ms"] + (r["median_collide_ms"] if with_collision else 0.0)
    quick = [r for r in runs if r["kind"] == "quickstep" and ran(r)]
    block = [r for r in runs if r["kind"] == "blockstep" and ran(r)]
    out = []
    for q in quick:
        winners = [b for b in block
                   if cost(b) <= cost(q) and b["error_m"] < q["error_m"]
                   and b["last_second_penetration_m"] <= q["last_second_penetration_m"] + 1e-4]
        affordable = [b for b in block if cost(b) <= cost(q)]
        best = min(affordable, key=lambda b: b["error_m"]) if affordable else None
        out.append((q, min(winners, key=cost) if winners else None, best))
    return out


def table_html(scene, runs):
    rows = []
    for r in runs:
        cls = r["kind"]
        ratio = r["solve_ratio_to_quickstep20"]
        rows.append(
            "<tr class='%s'><td>%s</td><td>%d</td><td>%.4f</td><td>%s</td><td>%.4f</td>"
            "<td>%s</td><td>%s</td><td>%.2f</td><td>%s</td><td>%s</td><td>%s</td><td>%s</td>"
            "<td>%.3g</td>"
            "<td>%.3g</td><td>%s</td></tr>"
            % (cls, html.escape(r["stepper"]), r["frames"], r["median_solve_ms"],
               "%.2f" % ratio if ratio > 0 else "", r["median_collide_ms"],
               mm(r["max_separation_m"]), mm(r["rms_separation_m"]),
               math.degrees(r["max_angle_rad"]), mm(r["max_penetration_m"]),
               mm(r.get("max_held_penetration_m", 0.0)), mm(r["last_second_penetration_m"]), mm(r["drift_m"]),
               r.get("max_energy_gain_j", 0.0), r.get("max_energy_rise_j", 0.0),
               html.escape(run_note(r))))
    return (
        "<table class='runs' data-scene='%s'><thead><tr><th>stepper</th><th>frames</th>"
        "<th>solve ms</th><th>&times; qs20</th><th>collide ms</th><th>max sep mm</th>"
        "<th>rms sep mm</th><th>max angle &deg;</th><th>max pen mm</th>"
        "<th title='the deepest contact whose pair touched at the collision before: one the "
        "stepper had a step to act on'>held pen mm</th><th>settled pen mm</th>"
        "<th>drift mm</th><th title='the most energy over the start'>E gain J</th>"
        "<th title='the most energy gained since the lowest so far'>E rise J</th>"
        "<th>note</th></tr></thead><tbody>%s</tbody></table>"
        % (html.escape(scene), "".join(rows)))


def standing_html(runs):
    entries = standing(runs)
    if not entries:
        return ""
    what = runs[0]["error_is"]
    beaten = sum(1 for _, w, _ in entries if w)
    items = []
    for q, winner, best in entries:
        head = "%s (%.3g ms, %s mm)" % (q["stepper"], q["median_solve_ms"], mm(q["error_m"]))
        if winner:
            items.append("<li class='win'>%s: beaten by %s (%.3g ms, %s mm)</li>" % (
                html.escape(head), html.escape(winner["stepper"]), winner["median_solve_ms"],
                mm(winner["error_m"])))
        elif best:
            items.append("<li class='loss'>%s: <b>not beaten</b>; blockstep's best at no more "
                         "time is %s (%.3g ms, %s mm, settled contact %s mm against %s)</li>" % (
                             html.escape(head), html.escape(best["stepper"]),
                             best["median_solve_ms"], mm(best["error_m"]),
                             mm(best["last_second_penetration_m"]),
                             mm(q["last_second_penetration_m"])))
        else:
            items.append("<li class='loss'>%s: <b>not beaten</b>; no blockstep setting run here "
                         "is as cheap</li>" % html.escape(head))
    by_frame = sum(1 for _, w, _ in standing(runs, with_collision=True) if w)
    return ("<p>%d of %d quickstep settings beaten by some blockstep setting at no more solve "
            "time (lower %s, settled contact no deeper); %d at no more solve and collision "
            "time:</p><ul>%s</ul>"
            % (beaten, len(entries), html.escape(what), by_frame, "".join(items)))


def paper_html(scenes):
    rows = []
    for scene, stepper, text, figure in PAPER_FIGURES:
        run = next((r for r in scenes.get(scene, []) if r["stepper"] == stepper and ran(r)), None)
        ours = ("%.3g ms (%s, max sep %s mm)" % (run["median_solve_ms"], stepper,
                                                  mm(run["max_separation_m"]))
                if run else "not run here")
        rows.append("<tr><td>%s</td><td>%s</td><td>%.3g ms</td><td>%s</td></tr>" % (
            html.escape(scene), html.escape(text), figure, html.escape(ours)))
    return ("<table class='paper'><thead><tr><th>scene</th><th>the paper</th><th>its time</th>"
            "<th>here (median solve per frame)</th></tr></thead><tbody>%s</tbody></table>"
            % "".join(rows))


def replay_data(out_dir, scene, runs):
    """Writes replay_<scene>.js; returns its index entry, or None when
    nothing was recorded."""
    scene_path = os.path.join(out_dir, "scene_%s.json" % scene)
    recorded = [r for r in runs if r.get("replay_file")
                and os.path.exists(os.path.join(out_dir, r["replay_file"]))]
    if not recorded or not os.path.exists(scene_path):
        return None
    with open(scene_path) as f:
        description = json.load(f)
    draw = description.get("draw", {})
    as_points = set(draw.get("surface", {}).get("bodies", []))
    for strand in draw.get("strands", []):
        as_points.update(strand)
    bodies = []
    for i, b in enumerate(description["bodies"]):
        bodies.append({"pose": 3 if i in as_points else 7, "geoms": b.get("geoms", [])})
    count = len(bodies)
    extent = 1.0
    out_runs = []
    for r in recorded:
        with open(os.path.join(out_dir, r["replay_file"]), "rb") as f:
            raw = f.read()
        values = struct.unpack("<%df" % (len(raw) // 4), raw)
        frames = len(values) // (7 * count) if count else 0
        if frames == 0:
            continue
        finite = [abs(v) for k, v in enumerate(values) if k % 7 < 3 and math.isfinite(v)]
        largest = max(finite) if finite else 1.0
        extent = max(extent, min(largest, 50.0))
        scale = 32000.0 / max(largest, 1e-3)
        packed = []
        for fr in range(frames):
            base = fr * 7 * count
            for i in range(count):
                k = base + 7 * i
                for c in range(bodies[i]["pose"]):
                    v = values[k + c]
                    v = 0.0 if not math.isfinite(v) else v
                    s = scale if c < 3 else QUATERNION_SCALE
                    packed.append(max(-32767, min(32767, int(round(v * s)))))
        data = struct.pack("<%dh" % len(packed), *packed)
        out_runs.append({"stepper": r["stepper"], "frames": frames, "positionScale": scale,
                         "note": run_note(r), "data": base64.b64encode(data).decode("ascii")})
    if not out_runs:
        return None
    frame_seconds = recorded[0].get("frame_dt", 1.0 / 60.0) * recorded[0]["replay_stride"]
    payload = {"scene": {"bodies": bodies, "static": description.get("static", []), "draw": draw},
               "extent": extent, "frameSeconds": frame_seconds, "runs": out_runs}
    name = "replay_%s.js" % scene
    with open(os.path.join(out_dir, name), "w") as f:
        f.write("window.BLOCKSTEP_REPLAY = window.BLOCKSTEP_REPLAY || {};\n")
        f.write("window.BLOCKSTEP_REPLAY[%s] = %s;\n" % (json.dumps(scene), json.dumps(payload)))
    steppers = [r["stepper"] for r in out_runs]
    # Open on quickstep 20 against blockstep's drop-in default when both ran.
    left = "quickstep:20" if "quickstep:20" in steppers else steppers[0]
    right = "blockstep" if "blockstep" in steppers else steppers[-1]
    return {"scene": scene, "file": name, "steppers": steppers, "left": left, "right": right}


STYLE = """
body { font-family: sans-serif; margin: 1.5em; color: #222; max-width: 1400px; }
table { border-collapse: collapse; font-size: 12px; margin: 0.5em 0 1em; }
th, td { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #eee; } td:first-child, td:last-child, table.paper td { text-align: left; }
tr.blockstep td { background: #eef4fb; } tr.pbd td, tr.xpbd td { background: #f6f6f6; }
li.loss { color: #9a2b12; } li.win { color: #1d5e2a; }
img { max-width: 100%; border: 1px solid #ddd; margin: 4px 0; }
#replay-canvas { width: 100%; height: 480px; display: block; background: #f4f4f0; }
#replay .captions { display: flex; } #replay .captions div { flex: 1; text-align: center; }
#replay .controls { margin: 6px 0; }
"""


def write_report(out_dir):
    has_runs = os.path.exists(os.path.join(out_dir, "summary.json"))
    scenes = plots.read_summary(out_dir) if has_runs else {}
    pngs = plots.plot_all(out_dir)
    index = []
    for scene, runs in scenes.items():
        entry = replay_data(out_dir, scene, runs)
        if entry:
            index.append(entry)
    if index:
        if not os.path.exists(THREE_JS):
            sys.exit("report.py: %s is missing (Debian's libjs-three: scripts/install-deps.sh "
                     "installs it)" % THREE_JS)
        shutil.copyfile(THREE_JS, os.path.join(out_dir, "three.min.js"))
        shutil.copyfile(os.path.join(HERE, "replay.js"), os.path.join(out_dir, "replay.js"))
    convergence = dict(plots.convergence_files(out_dir))
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>blockstep comparison"
             "</title><style>%s</style></head><body>" % STYLE,
             "<h1>blockstep against ODE</h1><p>Written %s from %s (blockstep-compare). Each "
             "row is one run of a scene by one stepper, measured the same way: joint separation "
             "from the joint geometry, the deepest contact (and the deepest held: found at the "
             "collision before too), the top box's drift, and the median "
             "solve time per frame (collision apart).</p>"
             % (time.strftime("%Y-%m-%d %H:%M"), html.escape(os.path.abspath(out_dir)))]
    parts.append("<h2>The paper's figures beside ours</h2>" + paper_html(scenes))
    if index:
        parts.append(
            "<h2>Replay</h2><div id='replay'><div class='controls'>scene <select id='replay-scene'>"
            "</select> left <select id='replay-left'></select> right <select id='replay-right'>"
            "</select> <button id='replay-play'>play</button> <input id='replay-frame' "
            "type='range' min='0' max='0' value='0' style='width:30%'> <span id='replay-time'>"
            "</span></div><div class='captions'><div id='replay-left-caption'></div>"
            "<div id='replay-right-caption'></div></div><canvas id='replay-canvas'></canvas>"
            "<p>Drag to turn, wheel to zoom. Cloth is drawn as a surface through its cells, hair "
            "as curves through its segments.</p></div>")
    for scene, runs in scenes.items():
        parts.append("<h2 id='scene-%s'>%s</h2>" % (html.escape(scene), html.escape(scene)))
        parts.append(table_html(scene, runs))
        parts.append(standing_html(runs))
        for png in ("cost_%s.png" % scene, "convergence_%s.png" % scene):
            if os.path.exists(os.path.join(out_dir, png)):
                parts.append("<img src='%s' alt='%s'>" % (png, png))
    for scene in convergence:
        if scene not in scenes and os.path.exists(os.path.join(out_dir, "convergence_%s.png" % scene)):
            parts.append("<h2>%s: convergence</h2><img src='convergence_%s.png'>" % (
                html.escape(scene), html.escape(scene)))
    parts.append("<pre id='selftest'></pre>")
    if index:
        parts.append("<script>window.BLOCKSTEP_REPLAY_INDEX = %s;</script>" % json.dumps(index))
        parts.append("<script src='three.min.js'></script><script src='replay.js'></script>")
    parts.append("</body></html>")
    path = os.path.join(out_dir, "report.html")
    with open(path, "w") as f:
        f.write("\n".join(parts))
    return path, pngs


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: report.py RESULTS_DIR")
    try:
        path, pngs = write_report(sys.argv[1])
    except (OSError, ValueError, KeyError) as e:
        sys.exit("report.py: cannot read the results in %s: %s" % (sys.argv[1], e))
    print("report.py: %d plots; wrote %s" % (len(pngs), path))


if __name__ == "__main__":
    main()
