#!/usr/bin/env bash
# The main job: builds blockstep and runs the A/B comparison of
# ../shared/SCENES.md's scenes stepped by ODE's quickstep, ODE's dWorldStep,
# blockstep and the paper's position-based baseline (blockstep-compare),
# printing the summary table, then the convergence study from one saved
# state, and writes the HTML report (results/compare/report.html: the
# table, error-versus-cost and convergence plots, a 3D replay) with one
# CSV per run and summary.json beside it. Installs missing Debian packages
# first (as root). Safe to run twice.
#
# Arguments go to blockstep-compare in place of the default comparison
# (--scene NAME, --stepper SPEC, --frames N, --help); the convergence
# study then runs only when --residuals is among them.
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target blockstep-compare blockstep_demo
out=results/compare
rm -rf "$out"
./build/compare/blockstep-compare --out "$out" "$@"
if [ $# -eq 0 ]; then
  # One step again and again with 1..50 sweeps from frame 60 of each scene.
  ./build/compare/blockstep-compare --out "$out" --residuals 60 --max-sweeps 50
fi
/usr/bin/python3 compare/report/report.py "$out"
