#!/usr/bin/env bash
# Sets up virtmech and runs the main job on the built-in PHANTOM Omni model: a servo loop
# holding the handle to a circle, printing the joint torques.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python examples/python/01_omni_loop.py
