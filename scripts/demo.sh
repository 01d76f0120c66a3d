#!/usr/bin/env bash
# Sets up virtmech with its simulation extras and runs the main job: the paper's Figs. 9-12
# simulated on the PHANTOM Omni and the Planar3R (MuJoCo), written to out/demo with one
# folder per scenario, summary.json and index.html.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh sim
.venv/bin/virtmech demo --out out/demo
