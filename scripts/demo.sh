#!/usr/bin/env bash
# The project's main job on the embedded default: simulates a 30-min E-Core 2000-like record
# (built-in preset, seed 1), writes it as E-Core binary frames, replays it through the
# firmware's fog-core pipeline and writes a report folder. Usage: scripts/demo.sh [OUT_DIR]
# (default out/demo); prints the path of OUT_DIR/index.html.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
cargo run --release -p host-sim -- demo --out "${1:-out/demo}"
