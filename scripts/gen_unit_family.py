#!/usr/bin/env python3
"""Gyro FAMILY generator (NumPy): many distinct units spread widely around the nominal, laid out
so that methods are tuned on some records (and units) and scored on others.

Reuses the physics of gen_nav_records.py (flicker(), thermal(), write(), FAMILY, VEHICLE) and adds
per-unit spread, a family-shared temperature link, log-uniform stop/drive durations and vibration.

Layout of one family (the CSV format of gen_nav_records / host-sim, a FILE.csv.json sidecar with
every drawn parameter, i.e. the truth, beside each CSV):
    DIR/family.json                    family parameters, options, every unit's draws, files
    DIR/train/static-NN.csv            static calibration runs, --n-train units
    DIR/static-test/static-NN.csv      --n-static-test other units, static
    DIR/vehicles-tune/vehicle-NN.csv   --n-vehicle-tune other units
    DIR/vehicles-test/vehicle-NN.csv   --n-vehicle-test other units
    (static-NN-rR.csv, power-on R, when --records-per-unit > 1)
    DIR/unit-runs/vehicle-NN-rR.csv    --unit-runs K static calibration runs (power-ons R = 1..K)
                                       of each vehicles-test unit NN: the user's own unit on the
                                       bench before it is flown (power-on 0 is its vehicle record)
    DIR/unit-runs/static-NN-rR.csv     the same for each static-test unit NN
Columns: t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving.

Drawn per unit (dph = deg/h; uniform unless said):
  noise factor f, log-uniform in --noise-spread (0.5..3): ARW 0.067 f deg/sqrt(h), per-sample
      white sigma = ARW / 60 * sqrt(fs) deg/s;
  turn-on centre +-50 dph (x --turn-on-scale); each power-on adds N(0, 5 dph) (x the same scale);
  warm-up a1 exp(-t/tau1) + a2 exp(-t/tau2): a1 +-40 dph, tau1 100..1500 s, a2 +-5 dph, tau2 10..120 s;
  bias instability 0.5..3 dph (flicker), rate random walk 0.2..1 dph/sqrt(h);
  temperature link (--temp-link, family option):
      weak    k1 +-0.05 dph/C, Shupe +-0.5 dph/(C/min), nothing shared across units;
      strong  k1 = K1 (1 + 0.2 z1), Shupe = S (1 + 0.2 z2), z ~ N(0,1) per unit, with the
              family-shared K1 = +-1.5 dph/C and S = +-(5..15) dph/(C/min) (signs random per
              family): the shared part is what a model trained across units should learn;
      both    k2 +-0.002 dph/C^2, T_ref 25 C.
Drawn per record (power-on): ambient start 0..40 C, self-heating 2..15 C, ambient ramp +-10 C/h,
thermal time constant 300..1500 s, the turn-on, the flicker, random-walk and white-noise paths.
drift_dps = turn-on + warm-up + flicker + random walk + k1 (T-Tref) + k2 (T-Tref)^2 + Shupe dT/dt
(temperature integrated by gen_nav_records.thermal on a 1 s grid, interpolated to the samples).

Vehicle records: a still alignment (--align-s), then drives and stops alternating, starting with a
drive; drives log-uniform 30..1200 s, stops log-uniform 5..300 s; a record of >= 1800 s holds one
drive of 1200..1500 s without a stop. Yaw as in gen_nav_records.vehicle_rate: road curvature
(Ornstein-Uhlenbeck) x speed, clipped, plus trapezoidal turns. moving = 1 in drives, 0 at stops
and in the alignment; true_rate_dps = 0 whenever moving = 0.
Vibration (vehicle records only; the engine runs throughout, alignment included):
  still: idle vibration of RMS r sigma, r uniform in --idle-vib (0.5..3) per record: m = 2 or 3
      engine harmonics k f0 (k = 1..m, all within 10..40 Hz) carrying 50..90 % of the variance,
      the rest band-pass noise 5..45 Hz;
  drives: road vibration, band-pass noise 2..60 Hz of RMS r sigma x (1..3).
  Both are evaluated at the sample instants with NO anti-alias filter, so content above fs/2
  folds (a harmonic may fold near 0 Hz and look like a slow bias over one stop). The vibration
  is zero-mean sensor-seen motion: it is in rate_dps but NOT in drift_dps nor true_rate_dps, so
  rate - true - drift = vibration + white + quantization. --idle-vib 0 0 disables all
  vibration (the road RMS scales with the idle one). Static records: no motion, no vibration.
Sensor: --rate-hz (20..2000), full scale +-60 deg/s (--full-scale-dps), quantum full scale /
32768 (60/32768 deg/s, E-Core-like); saturation, then rounding to the quantum.

ASSUMED (no datasheet value anywhere): every range and default above, in particular the nominal
ARW 0.067 deg/sqrt(h), the 0.2 unit spread around the shared link, the k2 range, T_ref 25 C,
100 Hz, the 16-bit quantum tied to full scale, the 120 s alignment, the 1200..1500 s long drive,
the vibration bands, harmonic share and road/idle ratio, the engine idling during the alignment,
the 10 Hz grid of the road curvature, and gen_nav_records.VEHICLE (speed, curvature, turns).

Deterministic: every draw comes from a PCG64 stream keyed (family seed, set, unit, record,
stream); sets 0 train, 1 static-test, 2 vehicles-tune, 3 vehicles-test, so units never repeat.

Usage:
    gen_unit_family.py --out DIR --family-seed S [--rate-hz F] [--temp-link weak|strong]
        [--noise-spread LO HI] [--idle-vib LO HI] [--duration-s 1800] [--align-s 120]
        [--n-train 12 --n-static-test 6 --n-vehicle-tune 6 --n-vehicle-test 6]
        [--records-per-unit 1] [--turn-on-scale 1] [--full-scale-dps 60] [--force]
    gen_unit_family.py --self-check
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gen_nav_records as g  # noqa: E402

DPH = g.DPH
SETS = [("train", "static", "n_train"), ("static-test", "static", "n_static_test"),
        ("vehicles-tune", "vehicle", "n_vehicle_tune"), ("vehicles-test", "vehicle", "n_vehicle_test")]
FAMILY_SET = 99  # stream key of the family-level draws
LINK_SPREAD = 0.2
DRIVE_S, STOP_S, LONG_DRIVE_S = (30.0, 1200.0), (5.0, 300.0), (1200.0, 1500.0)
HARMONIC_HZ, IDLE_BAND_HZ, ROAD_BAND_HZ = (10.0, 40.0), (5.0, 45.0), (2.0, 60.0)
COLUMNS = "t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving"


def rng(family_seed, set_idx, unit, rec, stream):
    return np.random.Generator(np.random.PCG64([family_seed, set_idx, unit, rec, stream]))


def loguniform(r, lo, hi):
    return float(math.exp(r.uniform(math.log(lo), math.log(hi))))


def draw_family(o):
    r = rng(o.family_seed, FAMILY_SET, 0, 0, 0)
    s1, s2 = (1.0 if x < 0.5 else -1.0 for x in r.random(2))
    shupe = r.uniform(5.0, 15.0)
    strong = o.temp_link == "strong"
    return {"rate_hz": o.rate_hz, "full_scale_dps": o.full_scale_dps,
            "quantum_dps": o.full_scale_dps / 32768.0, "t_ref_c": g.FAMILY["t_ref_c"],
            "nominal_arw_deg_rth": g.FAMILY["arw_deg_rth"], "temp_link": o.temp_link,
            "k1_dph_per_c": 1.5 * s1 if strong else None,
            "shupe_dph_per_c_per_min": shupe * s2 if strong else None,
            "link_unit_spread": LINK_SPREAD if strong else None}


def draw_unit(o, fam, set_idx, unit):
    r = rng(o.family_seed, set_idx, unit, 0, 0)
    f = loguniform(r, *o.noise_spread)
    arw = g.FAMILY["arw_deg_rth"] * f
    u = {"set": SETS[set_idx][0], "unit": unit, "key": [o.family_seed, set_idx, unit],
         "noise_factor": f, "arw_deg_rth": arw, "sigma_dps": arw / 60.0 * math.sqrt(fam["rate_hz"]),
         "turn_on_centre_dph": r.uniform(-50.0, 50.0) * o.turn_on_scale,
         "turn_on_sigma_dph": 5.0 * o.turn_on_scale,
         "warmup1_dph": r.uniform(-40.0, 40.0), "warmup1_tau_s": r.uniform(100.0, 1500.0),
         "warmup2_dph": r.uniform(-5.0, 5.0), "warmup2_tau_s": r.uniform(10.0, 120.0),
         "bias_instability_dph": r.uniform(0.5, 3.0), "rrw_dph_rth": r.uniform(0.2, 1.0),
         "k2_dph_per_c2": r.uniform(-0.002, 0.002)}
    z1, z2 = r.standard_normal(2)
    w1, w2 = r.uniform(-1.0, 1.0, 2)
    if fam["temp_link"] == "strong":
        u["k1_dph_per_c"] = fam["k1_dph_per_c"] * (1.0 + LINK_SPREAD * z1)
        u["shupe_dph_per_c_per_min"] = fam["shupe_dph_per_c_per_min"] * (1.0 + LINK_SPREAD * z2)
    else:
        u["k1_dph_per_c"], u["shupe_dph_per_c_per_min"] = 0.05 * w1, 0.5 * w2
    return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in u.items()}


def schedule(rem, need_long, r):
    """Alternating drive/stop segments [(moving, start, end)] (s after the alignment) filling
    rem s; with need_long one drive, starting early enough to fit, lasts 1200..1500 s."""
    durs = []
    while sum(durs) < rem:
        durs.append(loguniform(r, *(DRIVE_S if len(durs) % 2 == 0 else STOP_S)))
    starts = np.concatenate([[0.0], np.cumsum(durs)[:-1]])
    if need_long:  # a normal drive is <= 1200 s, so the list still covers rem afterwards
        fits = [i for i in range(0, len(durs), 2) if starts[i] <= rem - LONG_DRIVE_S[0]]
        durs[fits[int(r.integers(len(fits)))]] = r.uniform(*LONG_DRIVE_S)
        starts = np.concatenate([[0.0], np.cumsum(durs)[:-1]])
    return [(i % 2 == 0, float(s), float(min(s + d, rem)))
            for i, (s, d) in enumerate(zip(starts, durs)) if s < rem]


def motion(t, duration_s, align_s, r):
    """True yaw rate and moving flag of a vehicle record, and its segments (absolute times)."""
    v = g.VEHICLE
    rate, moving = np.zeros(len(t)), np.zeros(len(t), dtype=np.int8)
    rem = duration_s - align_s
    segs = schedule(rem, duration_s >= 1800.0, r) if rem > 0 else []
    # Road curvature: Ornstein-Uhlenbeck on a 10 Hz grid (correlation 20 s), interpolated.
    dtc, sig = 0.1, v["curvature_sigma_per_m"]
    tc = np.arange(0.0, duration_s + 2 * dtc, dtc)
    a = math.exp(-dtc * v["speed_mps"] / v["curvature_corr_m"])
    e = r.standard_normal(len(tc)) * sig * math.sqrt(1.0 - a * a)
    c = np.empty(len(tc))
    x = r.standard_normal() * sig
    for k in range(len(tc)):
        x = a * x + e[k]
        c[k] = x
    lim = v["road_max_dps"]
    road = np.clip(np.degrees(v["speed_mps"] * np.interp(t, tc, c)), -lim, lim)
    out = []
    for mv, s, e_ in segs:
        s, e_ = s + align_s, e_ + align_s
        out.append({"moving": int(mv), "start_s": s, "end_s": e_})
        if not mv:
            continue
        i, j = np.searchsorted(t, [s, e_])
        moving[i:j] = 1
        rate[i:j] = road[i:j]
        tt = s + r.exponential(v["turn_interval_s"])
        while True:  # trapezoidal turns (ramp, hold, ramp) as gen_nav_records.vehicle_rate
            peak = r.uniform(*v["turn_rate_dps"]) * (1.0 if r.random() < 0.5 else -1.0)
            ramp = v["turn_ramp_s"]
            dur = max(0.0, r.uniform(*v["turn_angle_deg"]) / abs(peak) - ramp) + 2.0 * ramp
            if tt + dur >= e_:
                break
            k0, k1 = np.searchsorted(t, [tt, tt + dur])
            u = t[k0:k1] - tt
            rate[k0:k1] += peak * np.clip(np.minimum(u, dur - u) / ramp, 0.0, 1.0)
            tt += dur + r.exponential(v["turn_interval_s"])
    return rate, moving, out


def band_noise(n, fs, band, r):
    """Unit-RMS noise, flat over band (Hz) in continuous time, sampled at fs with no anti-alias
    filter: synthesised at k fs >= 2.5 x the band edge and every k-th point kept."""
    k = max(1, int(math.ceil(2.5 * band[1] / fs)))
    spec = np.fft.rfft(r.standard_normal(n * k))
    f = np.fft.rfftfreq(n * k, d=1.0 / (k * fs))
    spec[(f < band[0]) | (f > band[1])] = 0.0
    x = np.fft.irfft(spec, n=n * k)[::k]
    return x / x.std()


def vibration(t, fs, moving, sigma, idle_vib, r):
    """Zero-mean sensor-seen vibration: engine idle at stops, road noise in drives."""
    if idle_vib[1] <= 0.0:
        return np.zeros(len(t)), {"enabled": False}
    ratio = r.uniform(*idle_vib)
    idle_rms = ratio * sigma
    m = int(r.integers(2, 4))
    f0 = r.uniform(HARMONIC_HZ[0], HARMONIC_HZ[1] / m)
    share = r.uniform(0.5, 0.9)
    amps = np.sqrt(2.0 * share * r.dirichlet(np.ones(m))) * idle_rms
    phases = r.uniform(0.0, 2.0 * math.pi, m)
    freqs = f0 * np.arange(1, m + 1)
    idle = math.sqrt(1.0 - share) * idle_rms * band_noise(len(t), fs, IDLE_BAND_HZ, r)
    for a, f, p in zip(amps, freqs, phases):
        idle += a * np.sin(2.0 * math.pi * f * t + p)
    road_rms = idle_rms * r.uniform(1.0, 3.0)
    road = road_rms * band_noise(len(t), fs, ROAD_BAND_HZ, r)
    meta = {"enabled": True, "idle_rms_over_sigma": ratio, "idle_rms_dps": idle_rms,
            "harmonic_hz": freqs.tolist(), "harmonic_amp_dps": amps.tolist(),
            "harmonic_phase_rad": phases.tolist(), "harmonic_variance_share": share,
            "idle_noise_band_hz": list(IDLE_BAND_HZ), "road_rms_dps": road_rms,
            "road_noise_band_hz": list(ROAD_BAND_HZ),
            "note": "in rate_dps only, not in drift_dps nor true_rate_dps; no anti-alias filter"}
    return np.where(moving == 1, road, idle), meta


def record(o, fam, u, kind, rec):
    """One power-on of unit u: (data columns, sidecar meta, vibration)."""
    key = (*u["key"], rec)
    fs = fam["rate_hz"]
    n = int(math.ceil(o.duration_s * fs))
    t = np.arange(n) / fs
    c = rng(*key, 1)
    cond = {"ambient_start_c": c.uniform(0.0, 40.0), "self_heating_c": c.uniform(2.0, 15.0),
            "ambient_ramp_c_per_h": c.uniform(-10.0, 10.0), "thermal_tau_s": c.uniform(300.0, 1500.0),
            "turn_on_dph": u["turn_on_centre_dph"] + c.standard_normal() * u["turn_on_sigma_dph"]}
    tc = np.arange(0.0, o.duration_s + 2.0, 1.0)  # thermal tau >= 300 s: a 1 s grid suffices
    temp_c = g.thermal(tc, cond["ambient_start_c"], cond["self_heating_c"],
                       cond["ambient_ramp_c_per_h"] / 3600.0, cond["thermal_tau_s"])
    temp, dtemp = np.interp(t, tc, temp_c), np.interp(t, tc, np.gradient(temp_c, tc))
    dt_ref = temp - fam["t_ref_c"]
    drift = DPH * (cond["turn_on_dph"]
                   + u["warmup1_dph"] * np.exp(-t / u["warmup1_tau_s"])
                   + u["warmup2_dph"] * np.exp(-t / u["warmup2_tau_s"])
                   + u["k1_dph_per_c"] * dt_ref + u["k2_dph_per_c2"] * dt_ref ** 2
                   + u["shupe_dph_per_c_per_min"] * 60.0 * dtemp)
    drift += g.flicker(n, fs, u["bias_instability_dph"] * DPH, rng(*key, 2))
    drift += np.cumsum(rng(*key, 3).standard_normal(n)) * u["rrw_dph_rth"] * DPH / 60.0 / math.sqrt(fs)
    if kind == "vehicle":
        true_rate, moving, segs = motion(t, o.duration_s, o.align_s, rng(*key, 4))
        vib, vmeta = vibration(t, fs, moving, u["sigma_dps"], o.idle_vib, rng(*key, 6))
    else:
        true_rate, moving, segs = np.zeros(n), np.zeros(n, dtype=np.int8), None
        vib, vmeta = np.zeros(n), {"enabled": False}
    white = rng(*key, 5).standard_normal(n) * u["sigma_dps"]
    raw = np.clip(true_rate + drift + vib + white, -fam["full_scale_dps"], fam["full_scale_dps"])
    rate = np.round(raw / fam["quantum_dps"]) * fam["quantum_dps"]
    meta = {"generator": "gen_unit_family.py", "kind": kind, "record": rec, "duration_s": o.duration_s,
            "family": fam, "sensor": u, "conditions": {k: float(v) for k, v in cond.items()},
            "vehicle": None if kind == "static" else {
                "align_s": o.align_s, "drive_s": list(DRIVE_S), "stop_s": list(STOP_S),
                "long_drive_s": list(LONG_DRIVE_S), "params": g.VEHICLE, "segments": segs},
            "vibration": vmeta, "columns": COLUMNS}
    return np.column_stack([t, rate, temp, drift, true_rate, moving]), meta, vib


def build_family(o):
    fam = draw_family(o)
    units = [draw_unit(o, fam, si, k) for si, s in enumerate(SETS) for k in range(getattr(o, s[2]))]
    return fam, units


def write_family(o):
    t0 = time.time()
    fam, units = build_family(o)
    kinds = dict((s[0], s[1]) for s in SETS)
    total = 0
    for u in units:
        d = os.path.join(o.out, u["set"])
        os.makedirs(d, exist_ok=True)
        u["records"] = []
        for rec in range(o.records_per_unit):
            suffix = "" if o.records_per_unit == 1 else "-r%d" % rec
            name = "%s-%02d%s.csv" % (kinds[u["set"]], u["unit"], suffix)
            data, meta, _ = record(o, fam, u, kinds[u["set"]], rec)
            path = os.path.join(d, name)
            g.write(path, data, meta)
            size = os.path.getsize(path)
            total += size
            u["records"].append({"file": os.path.join(u["set"], name),
                                 "turn_on_dph": meta["conditions"]["turn_on_dph"]})
            print("%s/%s: %d samples at %g Hz, noise x%.2f, turn-on %+.1f dph, %.1f MB" % (
                u["set"], name, len(data), fam["rate_hz"], u["noise_factor"],
                meta["conditions"]["turn_on_dph"], size / 1e6), file=sys.stderr)
    opts = {k: v for k, v in vars(o).items() if k not in ("self_check", "force")}
    doc = {"generator": "gen_unit_family.py", "options": opts, "family": fam,
           "sets": {s[0]: {"kind": s[1], "set_index": i} for i, s in enumerate(SETS)},
           "columns": COLUMNS, "units": units}
    fd, tmp = tempfile.mkstemp(dir=o.out, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(doc, f, indent=1, sort_keys=True)
    os.replace(tmp, os.path.join(o.out, "family.json"))
    n_files = len(units) * o.records_per_unit
    print("family seed %d: %d units, %d records of %g s at %g Hz (%s link) in %s, %.1f MB, %.1f s" % (
        o.family_seed, len(units), n_files, o.duration_s, fam["rate_hz"], fam["temp_link"], o.out,
        total / 1e6, time.time() - t0))


def write_unit_runs(o):
    """unit-runs/{vehicle,static}-NN-rR.csv: --unit-runs static power-ons (R = 1..K) of every
    vehicles-test and static-test unit; the unit's draws are the ones of its test record
    (power-on 0). Files already there are kept (a folder made before static-test runs were
    added gets only those)."""
    fam, units = build_family(o)
    d = os.path.join(o.out, "unit-runs")
    os.makedirs(d, exist_ok=True)
    n = 0
    kinds = {"vehicles-test": "vehicle", "static-test": "static"}
    for u in units:
        if u["set"] not in kinds:
            continue
        stem = "%s-%02d" % (kinds[u["set"]], u["unit"])
        for rec in range(1, o.unit_runs + 1):
            path = os.path.join(d, "%s-r%d.csv" % (stem, rec))
            if os.path.exists(path) and os.path.exists(path + ".json"):
                continue
            data, meta, _ = record(o, fam, u, "static", rec)
            meta["unit_runs_of"] = "%s/%s.csv" % (u["set"], stem)
            g.write(path, data, meta)
            n += 1
    print("unit-runs: %d static runs written in %s" % (n, d), file=sys.stderr)


def parser():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", help="family directory (refused if non-empty, unless --force)")
    ap.add_argument("--family-seed", type=int, default=0)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--temp-link", choices=["weak", "strong"], default="strong")
    ap.add_argument("--noise-spread", type=float, nargs=2, default=[0.5, 3.0], metavar=("LO", "HI"))
    ap.add_argument("--idle-vib", type=float, nargs=2, default=[0.5, 3.0], metavar=("LO", "HI"))
    ap.add_argument("--duration-s", type=float, default=1800.0)
    ap.add_argument("--align-s", type=float, default=120.0)
    for s in SETS:
        ap.add_argument("--" + s[2].replace("_", "-"), type=int, default=12 if s[0] == "train" else 6)
    ap.add_argument("--records-per-unit", type=int, default=1, help="power-ons per unit")
    ap.add_argument("--turn-on-scale", type=float, default=1.0)
    ap.add_argument("--full-scale-dps", type=float, default=60.0)
    ap.add_argument("--unit-runs", type=int, default=0,
                    help="static calibration runs of each vehicles-test unit (unit-runs/)")
    ap.add_argument("--unit-runs-only", action="store_true",
                    help="write only unit-runs/ into an existing family made with the same options")
    ap.add_argument("--force", action="store_true", help="overwrite a non-empty --out")
    ap.add_argument("--self-check", action="store_true")
    return ap


def check_white(data, vib, u, fam, what):
    res = data[:, 1] - data[:, 4] - data[:, 3] - vib
    want = math.sqrt(u["sigma_dps"] ** 2 + fam["quantum_dps"] ** 2 / 12.0)
    rho = np.corrcoef(res[:-1], res[1:])[0, 1]
    assert abs(res.std() / want - 1.0) < 0.05, (what, res.std(), want)
    assert abs(rho) < 4.0 / math.sqrt(len(res)), (what, "residual not white", rho)
    q = data[:, 1] / fam["quantum_dps"]
    assert np.allclose(q, np.round(q), atol=1e-6), (what, "quantized")
    return res.std() / want


def longest_run(m):
    d = np.diff(np.concatenate([[0], m.astype(int), [0]]))
    return int((np.flatnonzero(d == -1) - np.flatnonzero(d == 1)).max(initial=0))


def self_check():
    ap = parser()
    o = ap.parse_args(["--family-seed", "5", "--duration-s", "600"])
    fam, units = build_family(o)
    veh, sta = units[o.n_train + o.n_static_test], units[0]
    a, ma, va = record(o, fam, veh, "vehicle", 0)
    b, _, _ = record(o, build_family(o)[0], veh, "vehicle", 0)
    c, _, _ = record(o, fam, veh, "vehicle", 1)
    assert np.array_equal(a, b) and not np.array_equal(a, c), "determinism"
    o6 = ap.parse_args(["--family-seed", "6", "--duration-s", "600"])
    assert build_family(o6)[1][0] != units[0], "another family seed, other units"
    keys = [tuple(u["key"]) for u in units]
    assert len(set(keys)) == len(units) == len({u["noise_factor"] for u in units}), "units distinct"
    ratios = [check_white(a, va, veh, fam, "vehicle 100 Hz")]
    fs, still = fam["rate_hz"], a[:, 5] == 0
    align = slice(0, int(o.align_s * fs))
    assert not a[align, 5].any() and not a[align, 4].any(), "alignment still"
    assert a[:, 5].sum() > 0 and np.all(a[still, 4] == 0.0), "stops have zero true rate"
    r_idle = np.sqrt(np.mean(va[still] ** 2)) / veh["sigma_dps"]
    assert abs(r_idle / ma["vibration"]["idle_rms_over_sigma"] - 1.0) < 0.2, r_idle
    assert 0.5 <= ma["vibration"]["idle_rms_over_sigma"] <= 3.0, "idle RMS in --idle-vib"
    assert np.sqrt(np.mean(va[~still] ** 2)) >= 0.8 * ma["vibration"]["idle_rms_dps"], "road vibration"
    s, _, vs = record(o, fam, sta, "static", 0)
    assert not vs.any() and not s[:, 4].any() and not s[:, 5].any(), "static: no motion, no vibration"
    ratios.append(check_white(s, vs, sta, fam, "static 100 Hz"))
    o0 = ap.parse_args(["--family-seed", "5", "--duration-s", "600", "--idle-vib", "0", "0"])
    d0, m0, v0 = record(o0, fam, veh, "vehicle", 0)
    assert not v0.any() and not m0["vibration"]["enabled"], "vibration only when configured"
    ratios.append(check_white(d0, v0, veh, fam, "vehicle, no vibration"))
    for hz, spread in ((20.0, "0.5"), (1000.0, "3"), (2000.0, "1")):
        oh = ap.parse_args(["--family-seed", "7", "--duration-s", "150", "--align-s", "60",
                            "--rate-hz", str(hz), "--noise-spread", spread, spread])
        fh, uh = build_family(oh)
        u = uh[-1]
        dh, _, vh = record(oh, fh, u, "vehicle", 0)
        assert len(dh) == int(math.ceil(150.0 * hz)), (hz, len(dh))
        assert abs(np.diff(dh[:, 0]).mean() * hz - 1.0) < 1e-9 and vh.any(), hz
        ratios.append(check_white(dh, vh, u, fh, "vehicle %g Hz" % hz))
    ol = ap.parse_args(["--family-seed", "8", "--rate-hz", "20"])
    fl, ul = build_family(ol)
    dl, ml, _ = record(ol, fl, ul[-1], "vehicle", 0)
    assert longest_run(dl[:, 5]) >= 1200 * 20, "a >= 1200 s drive in an 1800 s record"
    for k in range(200):  # the schedule alone, many draws
        segs = schedule(1680.0, True, rng(9, 0, k, 0, 4))
        assert any(mv and e - st >= 1200.0 for mv, st, e in segs), k
        assert abs(segs[-1][2] - 1680.0) < 1e-9, "segments fill the record"
        assert all(x[2] == y[1] for x, y in zip(segs, segs[1:])), "segments contiguous"
    on = ap.parse_args(["--family-seed", "9", "--n-train", "400"])
    fn = [u["noise_factor"] for u in build_family(on)[1]]
    lo, hi = on.noise_spread
    assert lo <= min(fn) < lo * 1.05 and hi / 1.05 < max(fn) <= hi, (min(fn), max(fn))
    print("gen_unit_family self-check: ok (determinism, %d distinct units; residual rate-true-drift-vib "
          "std / sigma %s; idle vibration %.2f sigma; 20/1000/2000 Hz counts; 1200 s drive; noise "
          "factors %.3f..%.3f of [%g, %g])" % (len(units), " ".join("%.3f" % x for x in ratios),
                                                r_idle, min(fn), max(fn), lo, hi))


def main():
    ap = parser()
    o = ap.parse_args()
    if o.self_check:
        self_check()
        return 0
    if not o.out:
        ap.error("--out is required")
    if not (20.0 <= o.rate_hz <= 2000.0):
        ap.error("--rate-hz must be within 20..2000")
    if not (0.0 < o.noise_spread[0] <= o.noise_spread[1]):
        ap.error("--noise-spread needs 0 < LO <= HI")
    if not (0.0 <= o.idle_vib[0] <= o.idle_vib[1]):
        ap.error("--idle-vib needs 0 <= LO <= HI")
    if not (math.isfinite(o.duration_s) and o.duration_s > 0 and 0 <= o.align_s < o.duration_s):
        ap.error("need --duration-s > 0 and 0 <= --align-s < --duration-s")
    if o.duration_s >= 1800.0 and o.duration_s - o.align_s < LONG_DRIVE_S[0]:
        ap.error("a record of >= 1800 s needs 1200 s after the alignment for its long drive")
    if o.records_per_unit < 1 or min(getattr(o, s[2]) for s in SETS) < 0 or o.full_scale_dps <= 0:
        ap.error("need --records-per-unit >= 1, unit counts >= 0, --full-scale-dps > 0")
    if not (0 <= o.family_seed < 2 ** 32):
        ap.error("--family-seed must be within 0..2^32-1")
    if o.unit_runs < 0:
        ap.error("--unit-runs must be >= 0")
    if o.unit_runs_only:
        fj = os.path.join(o.out, "family.json")
        if not os.path.isfile(fj):
            ap.error("--unit-runs-only needs an existing family in --out (%s missing)" % fj)
        with open(fj) as f:
            made = json.load(f)["options"]
        for k, v in made.items():
            if k not in ("out", "unit_runs", "unit_runs_only") and getattr(o, k, v) != v:
                ap.error("--unit-runs-only: option %s is %r here but %r in %s" % (k, getattr(o, k), v, fj))
        write_unit_runs(o)
        return 0
    if os.path.isdir(o.out) and os.listdir(o.out):
        if not o.force:
            ap.error("%s exists and is not empty (use --force)" % o.out)
        for s in SETS:  # drop this generator's stale records, so a smaller family leaves none behind
            d = os.path.join(o.out, s[0])
            for fn in os.listdir(d) if os.path.isdir(d) else []:
                if fn.startswith(s[1] + "-") and (fn.endswith(".csv") or fn.endswith(".csv.json")):
                    os.remove(os.path.join(d, fn))
    os.makedirs(o.out, exist_ok=True)
    write_family(o)
    if o.unit_runs > 0:
        write_unit_runs(o)
    return 0


if __name__ == "__main__":
    sys.exit(main())
