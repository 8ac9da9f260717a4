#!/usr/bin/env python3
"""Checks that two blockstep-compare summaries hold the same runs with the
same results: everything but the times (which depend on what else ran).
Usage: same_results.py A/summary.json B/summary.json"""
import json
import sys

TIMES = {"median_solve_ms", "median_collide_ms", "solve_ratio_to_quickstep20"}


def results(path):
    with open(path) as f:
        return [{k: v for k, v in run.items() if k not in TIMES} for run in json.load(f)]


a, b = results(sys.argv[1]), results(sys.argv[2])
if not a:
    sys.exit(f"{sys.argv[1]}: no runs")
if a != b:
    for x, y in zip(a, b):
        if x != y:
            print(f"differs: {x}\n    and: {y}", file=sys.stderr)
    sys.exit(f"the summaries differ ({len(a)} and {len(b)} runs)")
print(f"same results in {len(a)} runs")
