#!/usr/bin/env bash
# fog-core denoise throughput against PyWavelets, side by side in one run, same data
# (2^20 samples, db4, 3 levels, soft universal threshold). Needs python3 with PyWavelets
# (installed with pip if missing). Prints both throughputs and the ratio.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -c "import pywt" 2>/dev/null || python3 -m pip install -q numpy PyWavelets
out=$(mktemp -d)
cargo bench -q -p fog-core --bench denoise -- --noplot 'denoise_db4_soft_3lvl/1048576' 2>&1 | tee "$out/fog.txt" >&2
python3 scripts/bench_pywt.py | tee "$out/pywt.txt" >&2
fog_ms=$(sed -n 's/.*time: *\[[0-9.]* [mµ]s \([0-9.]*\) \([mµ]\)s.*/\1 \2/p' "$out/fog.txt" | head -1)
python3 - "$fog_ms" "$out/pywt.txt" <<'PY'
import sys
v, unit = sys.argv[1].split()
fog_s = float(v) * (1e-3 if unit == "m" else 1e-6)
lines = open(sys.argv[2]).read().split("\n")
get = lambda key: float([l.split()[1] for l in lines if l.startswith(key + " ")][0])
pywt, pywt_med = get("pywt_samples_per_s"), get("pywt_samples_per_s_median")
fog = (1 << 20) / fog_s
# The headline ratio is the conservative one: fog-core's typical time (criterion's
# estimate) against PyWavelets' fastest of 20 runs. The typical-against-typical ratio
# follows in parentheses.
print(f"fog-core {fog/1e6:.1f} Msamples/s (criterion estimate), PyWavelets {pywt/1e6:.1f} Msamples/s (best of 20; median {pywt_med/1e6:.1f}): ratio {fog/pywt:.2f}x (against the median: {fog/pywt_med:.2f}x)")
PY
