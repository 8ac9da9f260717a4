#!/usr/bin/env bash
# The main job: builds blockstep and runs the A/B comparison of
# ../shared/SCENES.md's scenes stepped by ODE's quickstep, ODE's dWorldStep
# and blockstep (blockstep-compare), printing the summary table and
# writing one CSV per run, summary.json and error-versus-cost plots
# (cost_<scene>.png) to results/compare. Installs
# missing Debian packages first (as root). Safe to run twice. Arguments go
# to blockstep-compare (--scene NAME, --stepper SPEC, --frames N, --help).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target blockstep-compare blockstep_demo
./build/compare/blockstep-compare --out results/compare "$@"
# Error versus cost, one PNG per scene (Debian's matplotlib).
/usr/bin/python3 compare/plot_cost.py results/compare
