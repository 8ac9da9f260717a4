#!/usr/bin/python3
"""The comparison's HTML report, opened in headless Chromium.

Usage: report_in_chromium.py BLOCKSTEP_COMPARE REPORT_PY

Runs a short comparison (cloth, hair, a ragdoll, a stack and a chain; quickstep,
blockstep and XPBD where it can stand for the scene) and a short
convergence study, writes the report and opens report.html?selftest in
Debian's Chromium (software WebGL). The page's self-test loads every
scene's replay and draws its first and last frame on both sides. Checks:
no console errors, each side of the replay canvas drew (pixels other than
the background), every stepper that ran is in the replay's lists and
every run is in the summary table, and the plots the report shows exist.
"""
import json
import os
import re
import subprocess
import sys
import tempfile

CHROMIUM = "/usr/bin/chromium"


def fail(why):
    sys.exit("report_in_chromium: " + why)


def main():
    if len(sys.argv) != 3:
        fail("usage: report_in_chromium.py BLOCKSTEP_COMPARE REPORT_PY")
    compare, report = sys.argv[1], sys.argv[2]
    if not os.path.exists(CHROMIUM):
        fail("%s is missing (scripts/install-deps.sh installs Debian's chromium)" % CHROMIUM)
    out = tempfile.mkdtemp(prefix="blockstep-report-")
    run = [compare, "--scene", "cloth", "--size", "8", "--scene", "hair", "--scene", "ragdoll",
           "--scene", "stack", "--scene", "chain_swing", "--stepper", "quickstep:20", "--stepper", "blockstep",
           "--stepper", "xpbd:1x20", "--frames", "20", "--out", out]
    subprocess.run(run, check=True, stdout=subprocess.DEVNULL)
    subprocess.run([compare, "--residuals", "10", "--max-sweeps", "4", "--scene", "ragdoll",
                    "--out", out], check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["/usr/bin/python3", report, out], check=True, stdout=subprocess.DEVNULL)
    page = "file://" + os.path.join(out, "report.html") + "?selftest"
    browser = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--use-gl=swiftshader",
         "--enable-unsafe-swiftshader", "--window-size=1200,900", "--virtual-time-budget=30000",
         "--enable-logging=stderr", "--v=0", "--user-data-dir=" + os.path.join(out, "profile"),
         "--dump-dom", page],
        capture_output=True, text=True, timeout=300)
    dom = browser.stdout
    match = re.search(r'<pre id="selftest">([^<]*)</pre>', dom)
    if not match or not match.group(1):
        console = [line for line in browser.stderr.splitlines() if "CONSOLE" in line]
        fail("the page's self-test wrote nothing (Chromium exit %d; console:\n%s)"
             % (browser.returncode, "\n".join(console) or browser.stderr[-2000:]))
    found = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&"))

    # Console errors: the page's own record, and what Chromium logged.
    if found["errors"]:
        fail("console errors: %s" % found["errors"])
    logged = [line for line in browser.stderr.splitlines()
              if "CONSOLE" in line and ("Uncaught" in line or "Error" in line)]
    if logged:
        fail("Chromium logged console errors:\n" + "\n".join(logged))

    with open(os.path.join(out, "summary.json")) as f:
        runs = json.load(f)
    scenes = sorted({r["scene"] for r in runs})
    replayed = {s["scene"]: s for s in found["scenes"]}
    if sorted(replayed) != scenes:
        fail("replay scenes %s, runs of %s" % (sorted(replayed), scenes))
    for scene in scenes:
        ran = [r["stepper"] for r in runs if r["scene"] == scene and r["frames"] > 0]
        entry = replayed[scene]
        if entry["listed"] != ran:
            fail("%s: the replay lists %s, the runs were %s" % (scene, entry["listed"], ran))
        for frame, sides in zip(("first", "last"), entry["drawn"]):
            for side, pixels in zip(("left", "right"), sides):
                if pixels < 200:
                    fail("%s: the %s frame drew %d pixels on the %s" % (scene, frame, pixels, side))
        if entry["frames"] != 20 // 2 + 1:
            fail("%s: %d replay frames, 11 recorded" % (scene, entry["frames"]))
    for r in runs:
        row = "<td>%s</td>" % r["stepper"]
        table = re.search(r"<table class=\"runs\" data-scene=\"%s\">(.*?)</table>" % re.escape(
            r["scene"]), dom, re.S)
        if not table or row not in table.group(1):
            fail("the summary table of %s has no row for %s" % (r["scene"], r["stepper"]))
    for png in ["cost_%s.png" % s for s in scenes] + ["convergence_ragdoll.png"]:
        if png not in dom or not os.path.getsize(os.path.join(out, png)):
            fail("the report does not show %s" % png)
    if not found["ok"]:
        fail("the self-test did not pass: %s" % found)
    print("report_in_chromium: %d scenes replayed, %d runs listed, no console errors"
          % (len(scenes), len(runs)))
    subprocess.run(["rm", "-rf", out], check=False)


if __name__ == "__main__":
    main()
