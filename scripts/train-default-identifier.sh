#!/usr/bin/env bash
# Makes the identifier image the firmware embeds by default, fog-firmware/identifier/default.fogi:
# 12 static records of the E-Core 2000 family (`host-sim simulate --gyro ecore2000`, 1800 s at
# 100 Hz, record seeds 101..112, units 1..12 with a 20 % per-unit spread of the thermal and
# warm-up coefficients), then `host-sim identify --preset motion --save-identifier` (the gyro
# model fitted on them: host_sim::gyro_fit; sensor ecore2000; no vehicle to tune on, so the
# fitted scales as they are). Deterministic: the same code gives the same bytes.
#   bash scripts/train-default-identifier.sh [OUT.fogi]     (default: the committed file)
# Takes about a minute once host-sim is built (the debug build: the tests use it too; debug and
# release give the same bits, no fast-math).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-fog-firmware/identifier/default.fogi}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build -q -p host-sim --bin host-sim
bin=${CARGO_TARGET_DIR:-target}/debug/host-sim
mkdir -p "$work/train"
for i in $(seq 1 12); do
  "$bin" simulate --gyro ecore2000 --duration-s 1800 --seed $((100 + i)) \
    --unit-seed "$i" --unit-spread 0.2 --output "$work/train/static-$i.csv"
done
"$bin" identify --preset motion --gyro ecore2000 --input "$work/train" \
  --save-identifier "$work/default.fogi" --json "$work/identify.json"
mkdir -p "$(dirname "$out")"
cp "$work/default.fogi" "$out"
echo "wrote $out ($(wc -c < "$out") bytes, sha256 $(sha256sum "$out" | cut -d' ' -f1))"
