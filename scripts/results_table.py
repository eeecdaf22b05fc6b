#!/usr/bin/env python3
"""Markdown tables from the JSON reports of `host-sim reproduce` / `identify`.

    python3 scripts/results_table.py docs/results/repro-*.json

One row per report: the identifier's figures, then every causal baseline's e_truth
(the temperature-aware ones only in reports of records with a temp_c channel; "-" in
older reports), the best of them, and whether the identifier is below every one.
Null figures mean the identifier diverged (its output was NaN or infinite).
"""
import json
import sys


def f(v, fmt="{:.4f}"):
    return "diverged" if v is None else fmt.format(v)


def main(paths):
    print("| run | group | preset / trainer | lambda | e_rel | e_range | e_max | e_truth | RMS err vs truth (deg/h) | Kalman e_truth (q/r) | Kalman + temp. regression e_truth (q/r) | Kalman + batch LS of network basis e_truth | best MA e_truth (window) | MA of lagged target e_truth | below every baseline? | samples/s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for p in paths:
        r = json.load(open(p))
        c = r["config"]
        b = {x["name"]: x for x in r["baselines"]}
        kal = b["kalman_random_walk_q_over_r"]
        ma = b["moving_average_best_window_s"]
        lag = b["moving_average_of_target_lagged_one_block"]
        name = p.rsplit("/", 1)[-1].removeprefix("repro-").removesuffix(".json")
        level = c.get("level")
        level = (level if isinstance(level, str) else "kalman") if c["preset"] == "level-trend" else ""
        if c["preset"] == "level-bank":
            level = ("undelayed" if c.get("undelayed_output") else "delayed") + ("" if c.get("known_inputs", True) else ", no known inputs")
        treg = b.get("kalman_on_rate_minus_temperature_regression")
        tnet = b.get("kalman_on_rate_minus_batch_ls_of_network_basis")
        tcell = f"{f(treg['e_truth'])} ({treg['parameter']:g})" if treg else "-"
        ncell = f"{f(tnet['e_truth'])}" if tnet else "-"
        others = [x["e_truth"] for x in r["baselines"] if x["e_truth"] is not None]
        best = min(others) if others else None
        if r["e_truth"] is None or best is None:
            below = "no"
        else:
            below = f"{'yes' if r['e_truth'] < best else 'no'} ({r['e_truth'] - best:+.4f})"
        print(
            f"| {name} | {r.get('group', '-')} | {c['preset']} {level} / {c['trainer']}{' guarded' if c['guard'] else ''} | {c['lambda']} "
            f"| {f(r['e_rel'])} | {f(r['e_range'])} | {f(r['e_max'])} | {f(r['e_truth'])} | {f(r['rms_err_truth_dph'], '{:.2f}')} "
            f"| {f(kal['e_truth'])} ({kal['parameter']:g}) | {tcell} | {ncell} | {f(ma['e_truth'])} ({ma['parameter']:g} s) | {f(lag['e_truth'])} | {below} | {r['samples_per_s']:.0f} |"
        )
    r = json.load(open(paths[0]))
    i = r["identifier"]
    print()
    print(f"RMS(d) = {i['rms_d_dph']:.1f} deg/h, RMS(true drift) = {i['rms_truth_dph']:.1f} deg/h over {i['samples']} scored validation samples ({r['validate_records']} records; {r['train_records']} training records).")


if __name__ == "__main__":
    main(sys.argv[1:])
