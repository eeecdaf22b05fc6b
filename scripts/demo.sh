#!/usr/bin/env bash
# The project's main job: trains the motion identifier on 12 simulated static E-Core 2000
# family records (unit spread, per-record temperature), tunes its level and arrangement (dual
# or bank-guarded) and the gated Kalman baseline's q on 32 simulated vehicle records, replays
# a simulated 1800-s vehicle record with it and writes a report folder with the identifier
# beside the causal baselines (heading error RMS table and figure, 32 test vehicles). Usage: scripts/demo.sh [OUT_DIR] (default
# out/demo); prints the path of OUT_DIR/index.html.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo run --release -p host-sim -- demo --report "${1:-out/demo}"
