#!/usr/bin/env python3
"""Independent gyro-record generator for the `host-sim gap` benchmark (issue 13).

Requires: python3 and numpy (`pip install numpy`).

Written from the physics (IEEE Std 952 noise terms and the effect definitions below), NOT
from the project's simulator: its noise generation (flicker by FFT shaping, random walk by
cumulative sums, Gauss-Markov by the exact AR(1) recursion) and its parameter ranges are its
own, so a diagnosis tuned on the simulator cannot pass this benchmark by fitting one
generator.

Baseline (every record): white rate noise N, bias instability B (flicker rate noise, one-sided
PSD B^2 / (pi f), ADEV floor 0.664 B), rate random walk K, constant bias; drawn log-uniform
over wide ranges (tactical FOG to good MEMS). Sample rate 50, 100 or 200 Hz. 1800 s by
default. Plus exactly one effect (or none) with a dimensionless strength `s`, log-uniform
from barely detectable to strong (the definitions of `s` are in EFFECTS below and in
docs/gap.md). Some records carry a `temp_c` channel the drift does NOT follow (every class
but `temperature`, which always carries one it does follow), some a `true_rate_dps`
turntable motion (always for `scale_factor`).

Output: DIR/NAME.csv (t_s, rate_dps[, temp_c][, true_rate_dps]), DIR/NAME.toml (the nominal
baseline model (a gyro file), for `gap --gyro` mode: the N, B, K the record was made with, before any
baseline-type effect), DIR/manifest.jsonl (one line per record: truth and parameters).

Usage:
  scripts/gap_indep_gen.py --out DIR --first-seed 1 --per-class 6 [--classes a,b] [--duration-s 1800]
"""

import argparse
import json
import math
import os
import sys

import numpy as np

DEG_H = 1.0 / 3600.0  # deg/h in deg/s

# Classes usable without a user model (the baseline is fitted to the record).
FITTED_CLASSES = [
    "none", "quantization", "rate_ramp", "markov", "sinusoid", "temperature",
    "warmup", "spikes", "dropouts", "scale_factor",
]
# Baseline-type effects: only meaningful against a stated model (`gap --gyro`).
SIM_ONLY_CLASSES = ["white_noise", "bias_instability", "rate_random_walk"]

# Strength range per effect (log-uniform), see `effect()` for what s means.
S_RANGE = {
    "quantization": (0.01, 2.0),      # quantum / white sigma per sample
    "rate_ramp": (0.2, 20.0),         # ramp change over the record / D
    "markov": (0.2, 10.0),            # GM ADEV peak / baseline ADEV at tau = 1.9 T
    "sinusoid": (2.0, 60.0),          # A / sigma_w * sqrt(n / 2): line SNR in amplitude
    "temperature": (0.2, 20.0),       # RMS of the temperature-driven drift / D
    "warmup": (0.2, 20.0),            # transient amplitude / D
    "spikes": (1.0, 100.0),           # expected number of spikes
    "dropouts": (1.0, 2000.0),        # expected number of dropped samples
    "scale_factor": (2.0, 100.0),     # t-statistic of the SF slope: e rms(w) sqrt(n) / sigma_w
    "white_noise": (0.02, 1.0),       # actual N / model N - 1
    "bias_instability": (0.2, 5.0),   # actual B / model B - 1
    "rate_random_walk": (0.5, 30.0),  # actual K / model K - 1
}


def loguni(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def flicker(rng, n, dt, b_dps):
    """Flicker rate noise by FFT shaping of white noise on 2n samples (first n kept):
    one-sided PSD S(f) = B^2 / (pi f), whose Allan variance is (2 ln 2 / pi) B^2."""
    m = 2 * n
    w = rng.standard_normal(m)  # one-sided PSD 2 dt
    spec = np.fft.rfft(w)
    f = np.fft.rfftfreq(m, dt)
    gain = np.zeros_like(f)
    gain[1:] = np.sqrt(b_dps**2 / (math.pi * f[1:]) / (2.0 * dt))
    return np.fft.irfft(spec * gain, m)[:n]


def gauss_markov(rng, n, dt, sigma, tc):
    """First-order Gauss-Markov, exact discretisation x[k+1] = a x[k] + sigma sqrt(1-a^2) w."""
    a = math.exp(-dt / tc)
    q = sigma * math.sqrt(1.0 - a * a)
    w = rng.standard_normal(n) * q
    x = np.empty(n)
    x0 = sigma * rng.standard_normal()
    # AR(1) by blocks: x[k] = a^k x0 + sum a^(k-j) w[j]; use scipy-free recursion in chunks.
    acc = x0
    for k in range(n):
        acc = a * acc + w[k]
        x[k] = acc
    return x


def temperature_profile(rng, t):
    """True sensor temperature: warm-up rise, a slow cycle, a small random wander."""
    t0 = rng.uniform(15.0, 35.0)
    rise = rng.uniform(1.0, 10.0) * rng.choice([1.0, 1.0, -0.3])
    tau = rng.uniform(200.0, 1500.0)
    amp = rng.uniform(0.2, 2.0)
    per = rng.uniform(300.0, 1500.0)
    ph = rng.uniform(0, 2 * math.pi)
    dt = t[1] - t[0]
    wander = np.cumsum(rng.standard_normal(len(t))) * 0.002 * math.sqrt(dt)
    temp = t0 + rise * (1 - np.exp(-t / tau)) + amp * np.sin(2 * math.pi * t / per + ph) + wander
    return temp


def sensor_temp(rng, temp):
    """The recorded channel: 0.01 degC noise, 1/16 degC quantization (a typical sensor)."""
    return np.round((temp + 0.01 * rng.standard_normal(len(temp))) * 16.0) / 16.0


def smooth_derivative(temp, dt, win_s=30.0):
    """dT/dt: a 30-s moving mean, the window shrunk to the samples available at the ends
    (falling back to the raw series there made a jump, hence outliers in the drift of a
    strong dT/dt link, 15 s from each end), then np.gradient. The one-sided means at the ends
    lag: a linear temperature shows half its slope over the first and last 15 s (the drift
    is made from this same series, so the truth is what it says)."""
    k = max(1, int(round(win_s / dt)))
    ker = np.ones(k)
    sm = np.convolve(temp, ker, mode="same") / np.convolve(np.ones(len(temp)), ker, mode="same")
    return np.gradient(sm, dt)


def make_record(seed, cls, duration_s, mode, strength=None, fs=None, with_temp=False):
    rng = np.random.default_rng(seed)
    fs_draw = float(rng.choice([50.0, 100.0, 200.0]))
    fs = fs_draw if fs is None else fs
    dt = 1.0 / fs
    n = int(round(duration_s * fs))
    t = np.arange(n) * dt
    # Baseline, deg units.
    arw_dpsrh = loguni(rng, 0.005, 0.3)           # deg/sqrt(h)
    bi_dph = loguni(rng, 0.02, 3.0)               # deg/h
    rrw_dphrh = loguni(rng, 0.005, 1.0)           # deg/h/sqrt(h)
    n_dps = arw_dpsrh / 60.0
    b_dps = bi_dph * DEG_H
    k_dps = rrw_dphrh / 216000.0
    bias_dps = rng.uniform(-20.0, 20.0) * DEG_H
    sigma_w = n_dps / math.sqrt(dt)
    tau_blk = duration_s / 6.0
    d_scale = math.sqrt(n_dps**2 / tau_blk + 0.4413 * b_dps**2 + k_dps**2 * tau_blk / 3.0)
    model = {"arw_dps_per_rthz": n_dps, "bias_instability_dps": b_dps, "rrw_dps_per_s_rthz": k_dps}
    truth = {"seed": seed, "effect": cls, "fs_hz": fs, "duration_s": duration_s,
             "arw_deg_rth": arw_dpsrh, "bi_deg_h": bi_dph, "rrw_deg_h_rh": rrw_dphrh,
             "d_scale_dps": d_scale, "sigma_w_dps": sigma_w, "params": {}}
    s = None
    if cls != "none":
        lo, hi = S_RANGE[cls]
        s = loguni(rng, lo, hi)
        if strength is not None:
            s = strength
    truth["strength"] = s
    act = dict(model)
    if cls == "white_noise":
        act["arw_dps_per_rthz"] *= 1.0 + s
    elif cls == "bias_instability":
        act["bias_instability_dps"] *= 1.0 + s
    elif cls == "rate_random_walk":
        act["rrw_dps_per_s_rthz"] *= 1.0 + s
    y = bias_dps + act["arw_dps_per_rthz"] / math.sqrt(dt) * rng.standard_normal(n)
    y += flicker(rng, n, dt, act["bias_instability_dps"])
    y += np.cumsum(rng.standard_normal(n)) * act["rrw_dps_per_s_rthz"] * math.sqrt(dt)
    has_temp = cls == "temperature" or with_temp or rng.uniform() < 0.6
    temp_true = temperature_profile(rng, t) if has_temp else None
    has_motion = cls == "scale_factor" or rng.uniform() < 0.3
    motion = None
    if has_motion:
        motion = np.zeros(n)
        for _ in range(int(rng.integers(1, 4))):
            motion += loguni(rng, 2.0, 100.0) * np.sin(
                2 * math.pi * loguni(rng, 0.002, 0.2) * t + rng.uniform(0, 2 * math.pi))
        y += motion
    p = truth["params"]
    sign = float(rng.choice([-1.0, 1.0]))
    if cls == "rate_ramp":
        r = sign * s * d_scale / duration_s
        y += r * t
        p["ramp_deg_h_per_h"] = r * 3600.0 * 3600.0
    elif cls == "markov":
        tc = loguni(rng, 1.0, 60.0)
        base_adev = math.sqrt(n_dps**2 / (1.9 * tc) + 0.4413 * b_dps**2 + k_dps**2 * 1.9 * tc / 3.0)
        sigma = s * base_adev / 0.62
        y += gauss_markov(rng, n, dt, sigma, tc)
        p["gm_sigma_deg_h"] = sigma * 3600.0
        p["gm_tau_s"] = tc
    elif cls == "sinusoid":
        # Frequency: log-uniform 0.05 Hz - 0.4 fs, half the records within a factor 2 of 1 Hz.
        f = loguni(rng, 0.5, 2.0) if rng.uniform() < 0.5 else loguni(rng, 0.05, 0.4 * fs)
        a = s * sigma_w * math.sqrt(2.0 / n)
        y += a * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
        p["sine_amplitude_dps"] = a
        p["sine_freq_hz"] = f
    elif cls == "temperature":
        dtemp = smooth_derivative(temp_true, dt)
        x1 = temp_true - temp_true.mean()
        x2 = dtemp - dtemp.mean()
        mix = rng.uniform(0.0, 1.0)  # share of the dT/dt term in the drift RMS
        target = s * d_scale
        k1 = sign * target * math.sqrt(1.0 - mix) / max(x1.std(), 1e-9)
        k2 = float(rng.choice([-1.0, 1.0])) * target * math.sqrt(mix) / max(x2.std(), 1e-12)
        y += k1 * x1 + k2 * x2
        p["bias_deg_h_per_c"] = k1 * 3600.0
        p["bias_deg_h_per_c_per_s"] = k2 * 3600.0
        p["dtdt_share"] = mix
    elif cls == "warmup":
        tau = loguni(rng, 60.0, 600.0)
        a = sign * s * d_scale
        y += a * np.exp(-t / tau)
        p["warmup_deg_h"] = a * 3600.0
        p["warmup_tau_s"] = tau
    elif cls == "spikes":
        prob = s / n
        hit = rng.uniform(size=n) < prob
        amp = rng.uniform(5.0, 30.0, size=n) * sigma_w * rng.choice([-1.0, 1.0], size=n)
        y += np.where(hit, amp, 0.0)
        p["spike_probability"] = prob
        p["spikes"] = int(hit.sum())
    elif cls == "scale_factor":
        rms = float(np.sqrt(np.mean(motion**2)))
        e = sign * s * sigma_w / (rms * math.sqrt(n))
        y += e * motion
        p["scale_factor_ppm"] = e * 1e6
    elif cls == "quantization":
        q = s * sigma_w
        y = np.round(y / q) * q
        p["quantum_dps"] = q
    keep = np.ones(n, dtype=bool)
    if cls == "dropouts":
        # Runs of 1-5 samples start with probability s / (3 n) per sample.
        starts = np.nonzero(rng.uniform(size=n) < s / (3.0 * n))[0]
        for st in starts:
            keep[st: st + int(rng.integers(1, 6))] = False
        keep[0] = True
        p["dropped"] = int((~keep).sum())
    cols = {"t_s": t, "rate_dps": y}
    if has_temp:
        cols["temp_c"] = sensor_temp(rng, temp_true)
    if has_motion:
        cols["true_rate_dps"] = motion
    truth["has_temp"] = has_temp
    truth["has_motion"] = has_motion
    truth["mode"] = mode
    return cols, keep, model, truth, fs


def write_csv(path, cols, keep):
    names = list(cols)
    fmt = {"t_s": "%.6f", "rate_dps": "%.10g", "temp_c": "%.4f", "true_rate_dps": "%.8g"}
    arr = np.column_stack([cols[k][keep] for k in names])
    np.savetxt(path, arr, delimiter=",", header=",".join(names), comments="",
               fmt=[fmt[k] for k in names])


# The model's terms (deg/s units) as gyro-file keys (host_sim::gyro: datasheet units).
GYRO_KEYS = {
    "arw_dps_per_rthz": ("arw_deg_per_rth", 60.0),
    "bias_instability_dps": ("bias_instability_dph", 3600.0),
    "rrw_dps_per_s_rthz": ("rrw_dph_per_rth", 216000.0),
}


def write_toml(path, model, fs):
    """A gyro file (`host-sim gap --gyro PATH`) of the nominal model."""
    with open(path, "w") as f:
        f.write(f"sample_rate_hz = {fs}\n")
        for k, v in model.items():
            key, factor = GYRO_KEYS[k]
            f.write(f"{key} = {v * factor:.9e}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--per-class", type=int, default=6)
    ap.add_argument("--classes", default=None)
    ap.add_argument("--mode", choices=["fitted", "sim"], default="fitted",
                    help="fitted: classes usable without --gyro; sim: all 13 (run gap with --gyro NAME.toml)")
    ap.add_argument("--duration-s", type=float, default=1800.0)
    ap.add_argument("--strength", type=float, default=None, help="force the strength (smoke tests)")
    ap.add_argument("--with-temp", action="store_true", help="every record carries temp_c (smoke tests)")
    ap.add_argument("--fs", type=float, default=None, help="force the sample rate, Hz (smoke tests)")
    a = ap.parse_args()
    classes = (a.classes.split(",") if a.classes else
               FITTED_CLASSES + (SIM_ONLY_CLASSES if a.mode == "sim" else []))
    for c in classes:
        if c != "none" and c not in S_RANGE:
            sys.exit(f"unknown class {c}")
    os.makedirs(a.out, exist_ok=True)
    man = open(os.path.join(a.out, "manifest.jsonl"), "a")
    for ci, cls in enumerate(classes):
        for i in range(a.per_class):
            seed = a.first_seed + 1000 * ci + i
            name = f"{cls}-{seed}"
            cols, keep, model, truth, fs = make_record(seed, cls, a.duration_s, a.mode, a.strength, a.fs, a.with_temp)
            write_csv(os.path.join(a.out, name + ".csv"), cols, keep)
            write_toml(os.path.join(a.out, name + ".toml"), model, fs)
            truth["name"] = name
            man.write(json.dumps(truth) + "\n")
            man.flush()
            print(name, file=sys.stderr)


if __name__ == "__main__":
    main()
