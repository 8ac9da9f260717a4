#!/usr/bin/env bash
# The main job: builds blockstep and steps the benchmark scenes of
# ../shared/SCENES.md, printing a summary table. Installs missing Debian
# packages first (as root). Safe to run twice. Arguments go to the demo
# (--frames N, --scene NAME).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/install-deps.sh

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target blockstep_demo
./build/compare/blockstep_demo "$@"
