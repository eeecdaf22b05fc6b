#!/usr/bin/env bash
# The paper's section 5 reproduced on simulated records (265 x 1800 s, 180 train / 85
# validate; conditions in host-sim/src/identify/repro.rs), for the paper's exact
# configuration, the improved ones, every trainer, and the three condition groups.
# Writes docs/results/repro-*.json and prints one line per run. About 30-60 min on one core.
# Usage: bash scripts/reproduce-all.sh [RECORDS TRAIN]   (defaults 265 180)
set -euo pipefail
cd "$(dirname "$0")/.."
records=${1:-265}
train=${2:-180}
cargo build -q --release -p host-sim
out=docs/results
mkdir -p "$out"
run() {
  local name=$1; shift
  printf '%-34s ' "$name"
  ./target/release/host-sim reproduce --records "$records" --train-records "$train" "$@" --json "$out/repro-$name.json" 2>&1 | tail -1
}
run paper-exact                 --preset paper
run paper-guarded-sequential    --preset paper --trainer drls-sequential --guard true
run paper-guarded-seq-lambda999 --preset paper --trainer drls-sequential --guard true --lambda 0.999
run level-trend                 --preset level-trend
run level-kalman                --preset level-trend --level kalman --lambda 1 --u0 1e-6
# Levels at 3..1000 s (64-sample delay) + T, temperature, its rate; and its ablations.
run level-bank                  --preset level-bank
run level-bank-undelayed        --preset level-bank --undelayed-output
run level-bank-no-known-inputs  --preset level-bank --known-inputs false
run time-temp-bias30s           --preset time-temp --bias-memory-s 30
for g in stochastic quiet; do
  run "paper-exact-$g"  --group "$g" --preset paper
  run "level-trend-$g"  --group "$g" --preset level-trend
  run "level-kalman-$g" --group "$g" --preset level-trend --level kalman --lambda 1 --u0 1e-6
  run "level-bank-$g"   --group "$g" --preset level-bank
  run "level-bank-undelayed-$g" --group "$g" --preset level-bank --undelayed-output
done
# Trainers side by side on one smaller common set (full RLS at L = 30 costs ~3 L^2 per
# sample): 60 records, 40 train / 20 validate, nominal group.
records=60; train=40
run trainers60-drls-parallel      --preset level-trend --trainer drls-parallel
run trainers60-drls-sequential    --preset level-trend --trainer drls-sequential
run trainers60-rls                --preset level-trend --trainer rls --lambda 0.99999
run trainers60-nlms               --preset level-trend --trainer nlms --lambda 0.9999
run trainers60-paper-exact        --preset paper
# The temperature-input presets and their ablations on the same 60 records, three groups.
for g in nominal stochastic quiet; do
  run "small60-level-bank-$g"            --group "$g" --preset level-bank
  run "small60-level-bank-undelayed-$g"  --group "$g" --preset level-bank --undelayed-output
done
run small60-level-bank-no-known-inputs-nominal --preset level-bank --known-inputs false
run small60-time-temp-nominal          --preset time-temp
run small60-time-temp-bias30s-nominal  --preset time-temp --bias-memory-s 30
