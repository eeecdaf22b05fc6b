#!/usr/bin/env python3
"""`host-sim allan` on every real record and axis in ../shared/data/real (issue 43's goal).

For each record and gyro axis: run `allan` (the release binary), then report the worst
error of the fit against the measured Allan deviation over the taus the record supports
(at least 9 independent clusters; those are the fitted ones), the worst over every tau up
to a quarter of the record, the tau ranges the fit does not follow and the taus too long
for the record (both named by `allan` itself, with the reason), the model uncertainty and
the terms fitted. Records that turn are refused by `allan` (the static test `gap` uses):
their refusal is reported. Static parts of moving records are analysed as derived records
written to a temporary folder (never next to the data): the first 1.9 s of the four good
KVH 1750 logs and the first 50 s of the Xsens MTi recording (see each SOURCE.md).

Goal checked (exit status 1 when it fails): on every analysed record and axis, each
supported point within 25 % of the fit or named as not followed by `allan`; the points
between the last supported tau and a quarter of the record named as too long for the
record; model uncertainty <= 50 %.

Usage: cargo build --release -p host-sim && python3 scripts/allan_real_table.py [--markdown]
Skips (exit 0) when ../shared/data/real is absent. Standard library only.
"""

import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
REAL = os.path.normpath(os.path.join(ROOT, "..", "shared", "data", "real"))
BIN = os.environ.get("HOST_SIM", os.path.join(ROOT, "target", "release", "host-sim"))

# KVH logs without `t_s`: (true packet rate Hz, factor from dtheta deg to deg/s).
KVH = {
    "direct_imu_rate": (962.4, 1000.0),
    "direct_imu_delta": (962.4, 1000.0),
    "direct_ext_rate": (1000.0, 1000.0),
    "direct_ext_delta": (1000.0, 1000.0),
    "medulla_ext_rate": (500.0, 500.0),
    "medulla_ext_delta": (500.0, 500.0),
}
# KVH logs whose first 1.9 s are a usable static lead-in (the delta ones are corrupt).
KVH_LEAD = ["direct_imu_rate", "direct_imu_delta", "direct_ext_rate", "medulla_ext_rate"]
# Xsens MTi gyro gains, counts per rad/s (SOURCE.md).
XSENS_GAIN = {"x": 4778.0, "y": 4758.0, "z": 4766.0}


def cases(tmp):
    """(record label, axis, path, extra arguments) for every record and axis."""
    out = []
    adis = os.path.join(REAL, "adis16405_calgary")
    for run in range(1, 7):
        p = os.path.join(adis, f"adis16405_run{run}.csv.gz")
        for ax in "xyz":
            out.append((f"adis16405 run{run}", ax, p, ["--rate-column", f"g{ax}_dps"]))
    mpu = os.path.join(REAL, "mpu6050_sunsided")
    for f in sorted(os.listdir(mpu)):
        if f.endswith(".csv"):
            for ax in "xyz":
                out.append((f"mpu6050 {f[:-4]}", ax, os.path.join(mpu, f),
                            ["--rate-column", f"g{ax}_dps"]))
    kvh = os.path.join(REAL, "kvh1750_fog_yoos")
    for k, (hz, scale) in KVH.items():
        p = os.path.join(kvh, f"kvh_{k}.csv")
        for ax in "xyz":
            args = ["--rate-column", f"dtheta_{ax}_deg", "--rate-scale", str(scale),
                    "--rate-hz", str(hz)]
            out.append((f"kvh1750 {k}", ax, p, args))
            if k in KVH_LEAD:
                lead = os.path.join(tmp, f"kvh_{k}_first_1.9s.csv")
                if not os.path.exists(lead):
                    with open(p) as fi, open(lead, "w") as fo:
                        lines = fi.read().splitlines()
                        fo.write("\n".join(lines[: 1 + int(1.9 * hz)]) + "\n")
                out.append((f"kvh1750 {k} first 1.9 s", ax, lead, args))
    xs = os.path.join(REAL, "xsens_mti_imutk", "xsens_mti_raw.csv")
    lead = os.path.join(tmp, "xsens_first_50s.csv")
    with open(xs) as fi, open(lead, "w") as fo:
        for i, line in enumerate(fi):
            if i == 0 or float(line.split(",")[0]) < 50.0:
                fo.write(line)
    for ax in "xyz":
        args = ["--rate-column", f"g{ax}_counts", "--rate-scale",
                repr(180.0 / math.pi / XSENS_GAIN[ax])]
        out.append(("xsens_mti", ax, xs, args))
        out.append(("xsens_mti first 50 s", ax, lead, args))
    return out


def main():
    if not os.path.isdir(REAL):
        print(f"SKIPPED: {REAL} absent (no ../shared)")
        return 0
    if not os.path.exists(BIN):
        print(f"{BIN} absent: cargo build --release -p host-sim", file=sys.stderr)
        return 2
    md = "--markdown" in sys.argv
    failures = []
    rows = []
    stats = {"rel": []}
    with tempfile.TemporaryDirectory(prefix="allan_real_") as tmp:
        for label, ax, path, args in cases(tmp):
            js = os.path.join(tmp, "out.json")
            p = subprocess.run([BIN, "allan", "--input", path, "--json", js] + args,
                               capture_output=True, text=True)
            if p.returncode != 0:
                why = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else "?"
                short = why.split(": ", 2)[-1][:90]
                rows.append((label, ax, "refused", "", "", "", short))
                if "not a static record" not in why:
                    failures.append(f"{label} {ax}: refused for another reason: {why}")
                continue
            v = json.load(open(js))
            os.remove(js)
            dur = v["n_samples"] * v["tau0_s"]
            worst_sup, worst_q = 0.0, 0.0
            named = {round(m["tau_s"], 9) for m in v["fit"]["not_followed"]}
            for pt in v["points"]:
                e = pt["fit_adev_dps"] / pt["adev_dps"] - 1.0
                if pt["supported"]:
                    if abs(e) > abs(worst_sup):
                        worst_sup = e
                    if abs(e) > 0.25 and round(pt["tau_s"], 9) not in named:
                        failures.append(f"{label} {ax}: tau {pt['tau_s']:.4g} s off by {100*e:+.0f} %, not named")
                if pt["tau_s"] <= dur / 4 and abs(e) > abs(worst_q):
                    worst_q = e
            unsupported = [pt["tau_s"] for pt in v["points"] if not pt["supported"]]
            if unsupported and not any("too long for the record" in s for s in v["summary"]):
                failures.append(f"{label} {ax}: unsupported taus not named")
            rel = v["fit"]["model_rel"]
            stats["rel"].append(100 * rel)
            if rel > 0.5:
                failures.append(f"{label} {ax}: model uncertainty {100*rel:.1f} % > 50 %")
            terms = [t["symbol"] for t in v["fit"]["terms"] if t["active"]]
            if v["fit"].get("band_hz"):
                lo, hi = v["fit"]["band_hz"]
                terms = [t if t != "sigma_band" else f"band {lo:.3g}-{hi:.3g} Hz" for t in terms]
            if v["fit"].get("gm_tau_s"):
                terms = [t if t != "sigma_gm" else f"GM T={v['fit']['gm_tau_s']:.3g} s" for t in terms]
            nf = ", ".join(f"{m['tau_s']:.3g}" for m in v["fit"]["not_followed"])
            unsup = f"{min(unsupported):.3g}-{max(unsupported):.3g}" if unsupported else ""
            rows.append((label, ax, f"{100*worst_sup:+.1f} %", f"{100*worst_q:+.1f} %",
                         nf, unsup, f"{100*rel:.1f} %  {' + '.join(terms)}"))
    head = ("record", "axis", "worst, supported taus", "worst, to T/4",
            "not followed (tau s, named)", "too long (tau s, named)", "model unc., terms")
    if md:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for r in rows:
            print("| " + " | ".join(r) + " |")
    else:
        for r in [head] + rows:
            print(f"{r[0]:38s} {r[1]:4s} {r[2]:>9s} {r[3]:>9s}  {r[4]:24s} {r[5]:14s} {r[6]}")
    for f in failures:
        print("FAIL:", f, file=sys.stderr)
    analysed = [r for r in rows if r[2] != "refused"]
    named = [r for r in analysed if r[4]]
    print(f"{len(rows)} record-axes: {len(analysed)} analysed, {len(rows) - len(analysed)} "
          f"refused as not static; {sum(len(r[4].split(', ')) for r in named)} points not "
          f"followed, named, on {len(named)} record-axes; largest model uncertainty "
          f"{max(stats['rel'], default=0.0):.1f} %; {len(failures)} failures", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
