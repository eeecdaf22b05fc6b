#!/usr/bin/env python3
"""Second, independent FOG record generator (NumPy), written from the physics, NOT from
host-sim's simulator code, so that methods are never judged only on our own simulator.

Writes the interchange CSV of `host-sim simulate` with motion:
    t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving
and a sidecar FILE.json with every drawn parameter (the truth of the record).

Physics (deliberately different constructions from host-sim/src/sim):
- white rate noise (ARW N, deg/sqrt(h)): sigma = N/60 * sqrt(fs) deg/s per sample;
- bias instability B (deg/h): flicker rate noise synthesised in the FREQUENCY domain,
  two-sided PSD S(f) = B^2 / (2 pi f) (IEEE 952; Allan floor 0.664 B) for f >= 1/(2T);
- rate random walk K (deg/h/sqrt(h)): cumulative sum of white steps;
- turn-on bias: N(0, sigma) per power-on (the record seed);
- warm-up transient: a1 exp(-t/tau1) + a2 exp(-t/tau2) (two time constants; a2 = 0 gives
  the single exponential);
- temperature: first-order thermal model integrated step by step,
  dT/dt = (T_amb(t) + rise - T) / tau_th, T(0) = T_amb(0), ambient ramping slowly;
- thermal bias k1 (T - T_ref) + k2 (T - T_ref)^2 and the Shupe term s dT/dt;
- quantization (round to the sensor quantum) and saturation at +-full scale.
drift_dps = every term above except white noise, quantization and saturation.

Motion (vehicle): a still alignment period, then a two-state Markov chain (still / drive)
with EXPONENTIAL durations; in a drive the yaw rate is speed x curvature, the curvature an
Ornstein-Uhlenbeck process, clipped at road_max_dps, plus turns with a TRAPEZOIDAL rate
profile (ramp, hold, ramp). moving = 1 during a drive, 0 when still.

A gyro family: unit coefficients (warm-up, thermal, Shupe) are the family's times
(1 + spread z), z ~ N(0,1) from --unit-seed; each record (--seed) draws its own ambient
start, self-heating rise and ambient ramp. --ood draws the noise (x0.3..x3, log-uniform),
warm-up amplitude and time constants, thermal coefficients, sample rate (100 Hz..1 kHz)
and turn statistics over wide ranges. ALL default values are ASSUMED E-Core-2000-class
figures, not datasheet values.

Deterministic by seed (numpy PCG64 streams). Usage:
    gen_nav_records.py --kind static|vehicle --seed N --duration-s D --out FILE.csv
        [--unit-seed U --unit-spread 0.2] [--ood] [--rate-hz F]
    gen_nav_records.py --self-check
"""

import argparse
import json
import math
import os
import sys
import tempfile

import numpy as np

DPH = 1.0 / 3600.0  # deg/h in deg/s

FAMILY = {  # ASSUMED nominal family (E-Core 2000 class)
    "rate_hz": 100.0,
    "full_scale_dps": 60.0,
    "quantum_dps": 60.0 / 32768.0,
    "arw_deg_rth": 0.067,
    "bias_instability_dph": 1.5,
    "rrw_dph_rth": 0.5,
    "turn_on_sigma_dph": 5.0,
    "warmup1_dph": 3.0,
    "warmup1_tau_s": 600.0,
    "warmup2_dph": 0.0,
    "warmup2_tau_s": 60.0,
    "k1_dph_per_c": 0.1,
    "k2_dph_per_c2": 0.0,
    "shupe_dph_per_c_per_min": 1.0,
    "t_ref_c": 25.0,
    "thermal_tau_s": 900.0,
}

VEHICLE = {  # ASSUMED road vehicle
    "align_s": 300.0,
    "mean_stop_s": 30.0,
    "mean_drive_s": 150.0,
    "speed_mps": 15.0,
    "curvature_sigma_per_m": 5e-4,
    "curvature_corr_m": 300.0,
    "road_max_dps": 3.0,
    "turn_interval_s": 60.0,
    "turn_rate_dps": [5.0, 30.0],
    "turn_angle_deg": [20.0, 120.0],
    "turn_ramp_s": 1.0,
}


def rng_for(seed, stream):
    return np.random.Generator(np.random.PCG64([int(seed), int(stream)]))


def draw_unit(unit_seed, spread, ood, ood_rng):
    p = dict(FAMILY)
    if ood:
        r = ood_rng
        for k in ("arw_deg_rth", "bias_instability_dph", "rrw_dph_rth"):
            p[k] *= math.exp(r.uniform(math.log(0.3), math.log(3.0)))
        p["warmup1_dph"] = r.uniform(-10.0, 10.0)
        p["warmup1_tau_s"] = r.uniform(60.0, 1800.0)
        p["warmup2_dph"] = r.uniform(-3.0, 3.0)
        p["warmup2_tau_s"] = r.uniform(10.0, 120.0)
        p["k1_dph_per_c"] = r.uniform(-0.5, 0.5)
        p["k2_dph_per_c2"] = r.uniform(-0.01, 0.01)
        p["shupe_dph_per_c_per_min"] = r.uniform(-5.0, 5.0)
        p["thermal_tau_s"] = r.uniform(300.0, 2400.0)
        p["rate_hz"] = float(r.choice([100.0, 200.0, 250.0, 500.0, 1000.0]))
    if unit_seed is not None and spread > 0.0:
        u = rng_for(unit_seed, 101)
        for k in ("warmup1_dph", "warmup1_tau_s", "warmup2_dph", "k1_dph_per_c",
                  "k2_dph_per_c2", "shupe_dph_per_c_per_min", "thermal_tau_s"):
            f = 1.0 + spread * u.standard_normal()
            p[k] *= max(f, 0.1) if k.endswith("tau_s") else f
    return p


def flicker(n, fs, b_dps, rng):
    """Flicker rate noise of two-sided PSD B^2 / (2 pi f), frequency-domain synthesis."""
    if b_dps <= 0.0 or n < 4:
        return np.zeros(n)
    m = 1 << int(math.ceil(math.log2(2 * n)))
    f = np.fft.rfftfreq(m, d=1.0 / fs)
    s = np.zeros_like(f)
    s[1:] = b_dps ** 2 / (2.0 * math.pi * f[1:])
    w = rng.standard_normal(m)
    # s is two-sided (IEEE 952 convention): one-sided 2 s; unit white noise has one-sided
    # PSD 2 / fs, so the amplitude gain is sqrt(s fs).
    x = np.fft.irfft(np.fft.rfft(w) * np.sqrt(s * fs), n=m)
    return x[:n]


def thermal(t, amb0, rise, ramp, tau):
    """First-order case temperature, explicit integration (sub-stepped)."""
    temp = np.empty_like(t)
    x = amb0
    prev = t[0]
    for i, ti in enumerate(t):
        dt = ti - prev
        steps = max(1, int(math.ceil(dt / (0.05 * tau))))
        h = dt / steps
        for j in range(steps):
            amb = amb0 + ramp * (prev + (j + 1) * h)
            x += h * (amb + rise - x) / tau
        prev = ti
        temp[i] = x
    return temp


def vehicle_rate(t, v, rng):
    n = len(t)
    rate = np.zeros(n)
    moving = np.zeros(n, dtype=np.int8)
    dt = t[1] - t[0] if n > 1 else 1.0
    i = int(np.searchsorted(t, v["align_s"]))
    driving = True
    tau_c = v["curvature_corr_m"] / v["speed_mps"]
    while i < n:
        mean = v["mean_drive_s"] if driving else v["mean_stop_s"]
        length = max(1, int(rng.exponential(mean) / dt))
        j = min(n, i + length)
        if driving:
            moving[i:j] = 1
            c = rng.standard_normal() * v["curvature_sigma_per_m"]
            a = math.exp(-dt / tau_c)
            road = np.empty(j - i)
            for k in range(j - i):
                c = a * c + math.sqrt(1 - a * a) * v["curvature_sigma_per_m"] * rng.standard_normal()
                road[k] = math.degrees(v["speed_mps"] * c)
            rate[i:j] = np.clip(road, -v["road_max_dps"], v["road_max_dps"])
            k = i + int(rng.exponential(v["turn_interval_s"]) / dt)
            while True:
                peak = rng.uniform(*v["turn_rate_dps"]) * rng.choice([-1.0, 1.0])
                angle = rng.uniform(*v["turn_angle_deg"])
                ramp = v["turn_ramp_s"]
                hold = max(0.0, angle / abs(peak) - ramp)  # area = |peak| (hold + ramp)
                dur = hold + 2 * ramp
                m = int(math.ceil(dur / dt))
                if k + m >= j:
                    break
                u = np.arange(m) * dt
                shape = np.minimum(1.0, np.minimum(u / ramp, (dur - u) / ramp))
                rate[k:k + m] += peak * np.clip(shape, 0.0, 1.0)
                k += m + int(rng.exponential(v["turn_interval_s"]) / dt)
        i = j
        driving = not driving
    return rate, moving


def generate(kind, seed, duration_s, unit_seed=None, unit_spread=0.0, ood=False, rate_hz=None):
    ood_rng = rng_for(seed, 7)
    p = draw_unit(unit_seed, unit_spread, ood, rng_for(unit_seed if unit_seed is not None else seed, 8)
                  if ood else ood_rng)
    if rate_hz:
        p["rate_hz"] = float(rate_hz)
    fs = p["rate_hz"]
    n = int(math.ceil(duration_s * fs))
    t = np.arange(n) / fs
    rec = rng_for(seed, 1)
    cond = {
        "ambient_start_c": rec.uniform(10.0, 35.0),
        "self_heating_c": rec.uniform(2.0, 8.0),
        "ambient_ramp_c_per_h": rec.uniform(-5.0, 5.0),
        "turn_on_dps": rec.standard_normal() * p["turn_on_sigma_dph"] * DPH,
    }
    v = dict(VEHICLE)
    if ood and kind == "vehicle":
        v["mean_drive_s"] = ood_rng.uniform(30.0, 400.0)
        v["mean_stop_s"] = ood_rng.uniform(5.0, 120.0)
        v["turn_interval_s"] = ood_rng.uniform(10.0, 200.0)
        v["turn_rate_dps"] = [2.0, ood_rng.uniform(10.0, 55.0)]
    temp = thermal(t, cond["ambient_start_c"], cond["self_heating_c"],
                   cond["ambient_ramp_c_per_h"] / 3600.0, p["thermal_tau_s"])
    dtemp = np.gradient(temp, t) if n > 1 else np.zeros(n)
    drift = (cond["turn_on_dps"]
             + p["warmup1_dph"] * DPH * np.exp(-t / p["warmup1_tau_s"])
             + p["warmup2_dph"] * DPH * np.exp(-t / p["warmup2_tau_s"])
             + flicker(n, fs, p["bias_instability_dph"] * DPH, rng_for(seed, 2))
             + np.cumsum(rng_for(seed, 3).standard_normal(n)) * p["rrw_dph_rth"] * DPH / 60.0 / math.sqrt(fs)
             + p["k1_dph_per_c"] * DPH * (temp - p["t_ref_c"])
             + p["k2_dph_per_c2"] * DPH * (temp - p["t_ref_c"]) ** 2
             + p["shupe_dph_per_c_per_min"] * DPH * 60.0 * dtemp)
    if kind == "vehicle":
        true_rate, moving = vehicle_rate(t, v, rng_for(seed, 4))
    else:
        true_rate, moving = np.zeros(n), np.zeros(n, dtype=np.int8)
    white = rng_for(seed, 5).standard_normal(n) * p["arw_deg_rth"] / 60.0 * math.sqrt(fs)
    raw = np.clip(true_rate + drift + white, -p["full_scale_dps"], p["full_scale_dps"])
    rate = np.round(raw / p["quantum_dps"]) * p["quantum_dps"]
    meta = {"kind": kind, "seed": seed, "unit_seed": unit_seed, "unit_spread": unit_spread,
            "ood": ood, "sensor": p, "conditions": cond,
            "vehicle": v if kind == "vehicle" else None,
            "columns": "t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving"}
    return np.column_stack([t, rate, temp, drift, true_rate, moving]), meta


def write(path, data, meta):
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(meta["columns"] + "\n")
        np.savetxt(f, data, fmt=["%.6f", "%.10g", "%.6f", "%.10g", "%.10g", "%d"], delimiter=",")
    os.replace(tmp, path)
    with open(path + ".json", "w") as f:
        json.dump(meta, f, indent=1, sort_keys=True)


def adev(x, fs, m):
    """Non-overlapping Allan deviation of rate x at cluster size m."""
    k = len(x) // m
    means = x[:k * m].reshape(k, m).mean(axis=1)
    return math.sqrt(0.5 * np.mean(np.diff(means) ** 2))


def self_check():
    a, _ = generate("vehicle", 3, 600.0, unit_seed=1, unit_spread=0.2)
    b, _ = generate("vehicle", 3, 600.0, unit_seed=1, unit_spread=0.2)
    c, _ = generate("vehicle", 4, 600.0, unit_seed=1, unit_spread=0.2)
    assert np.array_equal(a, b), "same seed, same record"
    assert not np.array_equal(a, c), "other seed, other record"
    # The residual rate - true - drift is white noise + quantization.
    res = a[:, 1] - a[:, 4] - a[:, 3]
    sigma = FAMILY["arw_deg_rth"] / 60.0 * math.sqrt(FAMILY["rate_hz"])
    want = math.sqrt(sigma ** 2 + FAMILY["quantum_dps"] ** 2 / 12.0)
    assert abs(res.std() / want - 1.0) < 0.05, (res.std(), want)
    q = a[:, 1] / FAMILY["quantum_dps"]
    assert np.allclose(q, np.round(q), atol=1e-6), "quantized"
    moving = a[:, 5]
    assert moving[: int(300 * FAMILY["rate_hz"])].sum() == 0, "alignment still"
    assert moving.sum() > 0, "the vehicle moves"
    assert np.all(a[moving == 0, 4] == 0.0), "still means rate 0"
    assert np.abs(a[:, 4]).max() <= VEHICLE["road_max_dps"] + VEHICLE["turn_rate_dps"][1] + 1e-9
    # Flicker floor: Allan deviation of flicker alone near 0.664 B at mid taus.
    fs, bd = 10.0, 1.5 * DPH
    x = flicker(400000, fs, bd, rng_for(9, 2))
    ratio = [adev(x, fs, m) / (0.664 * bd) for m in (100, 1000)]
    assert all(0.88 < r < 1.12 for r in ratio), ratio
    # Saturation and OOD draws stay in their ranges; sample rate from the sensor config.
    d, meta = generate("vehicle", 5, 60.0, ood=True)
    assert 100.0 <= meta["sensor"]["rate_hz"] <= 1000.0
    assert len(d) == int(math.ceil(60.0 * meta["sensor"]["rate_hz"]))
    assert np.abs(d[:, 1]).max() <= meta["sensor"]["full_scale_dps"]
    s, _ = generate("static", 6, 100.0)
    assert np.all(s[:, 4] == 0.0) and np.all(s[:, 5] == 0)
    print("gen_nav_records self-check: ok (determinism, white residual %.4g vs %.4g deg/s, "
          "flicker floor ratios %.3f %.3f)" % (res.std(), want, ratio[0], ratio[1]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kind", choices=["static", "vehicle"], default="vehicle")
    ap.add_argument("--seed", type=int, default=0, help="record (power-on) seed")
    ap.add_argument("--duration-s", type=float, default=1800.0)
    ap.add_argument("--unit-seed", type=int, default=None)
    ap.add_argument("--unit-spread", type=float, default=0.0)
    ap.add_argument("--ood", action="store_true", help="draw parameters over wide ranges")
    ap.add_argument("--rate-hz", type=float, default=None)
    ap.add_argument("--out", help="output CSV (a FILE.json sidecar is written beside it)")
    ap.add_argument("--self-check", action="store_true")
    a = ap.parse_args()
    if a.self_check:
        self_check()
        return 0
    if not a.out:
        ap.error("--out is required")
    if not (a.duration_s > 0 and math.isfinite(a.duration_s)):
        ap.error("--duration-s must be finite and > 0")
    if a.rate_hz is not None and not (a.rate_hz > 0 and math.isfinite(a.rate_hz)):
        ap.error("--rate-hz must be finite and > 0")
    data, meta = generate(a.kind, a.seed, a.duration_s, a.unit_seed, a.unit_spread, a.ood, a.rate_hz)
    write(a.out, data, meta)
    print("%s: %d samples at %g Hz (%s, seed %d) -> %s" % (
        a.kind, len(data), meta["sensor"]["rate_hz"], "ood" if a.ood else "family", a.seed, a.out),
        file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
