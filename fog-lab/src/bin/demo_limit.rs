//! The demo's exact-model Kalman filter: on each of the demo's 32 test vehicles, the filter of
//! that vehicle's exact simulator model (f64), with the truth's still flags.
//!
//! The simulator (`host_sim::sim`) is run twice per vehicle with the same seeds: as the
//! demo runs it, and with its random drift terms off (bias instability, rate random walk,
//! Gauss-Markov noise, the random part of the turn-on; white noise off too). Its streams
//! are one per term, so the second run's drift is exactly the deterministic part of the
//! first's (turn-on centre, warm-up, temperature links, ramp, sine, scale factor). The
//! filter knows that part exactly and estimates the rest with the model's own states: the
//! random turn-on (a constant of the model's sigma), each process of the flicker bank
//! (stationary Gauss-Markov terms at the bank's correlation times and variance), the rate
//! random walk (from 0) and the Gauss-Markov term. Measurements: `rate - true rate` at the
//! truth's still samples, noise the white noise plus the quantization's `q^2 / 12`.
//! It is the per-sample least-squares estimate (each sample's drift given the past), which
//! is not the least heading error: a heading integrates the errors, and errors that persist
//! through a drive add up. Measured (`demo_limit --summary`, docs/drift-filter.md "The
//! demo's exact model"): on the demo's flicker-dominated family it loses to a random walk
//! of larger q on the same measurements, so it is a reference, not a bound.
//! Beside it, that random walk (the demo's baseline q `1e-11 (deg/s)^2` per sample and
//! `r = 1.237e-4 (deg/s)^2`) on the same truth flags.
//!
//! ```sh
//! cargo run --release -p fog-lab --bin demo_limit -- [--summary DEMO_OUT/summary.json]
//! ```
//! With `--summary` (the demo's `--report` folder's `summary.json`) each vehicle's figure is
//! set beside the demo's rows: on how many vehicles it is below every baseline.

use anyhow::{bail, Context, Result};
use clap::Parser;
use fog_core::kalman::{DiagonalModel, Kalman};
use host_sim::demo::{family_model, samples, VEHICLE_SEED, VEHICLE_UNIT};
use host_sim::nav::{self, NavRecord};
use host_sim::sim::{flicker_times_s, flicker_unit_var, realize};
use serde_json::Value;
use std::path::PathBuf;

/// The demo's baseline random walk: q per sample, (deg/s)^2 (its tuned value).
const RW_Q_DPS2: f64 = 1e-11;
/// Its measurement noise, (deg/s)^2 (the demo's `r`).
const RW_R_DPS2: f64 = 1.237e-4;
/// Its initial variance, (deg/s)^2 (wide: about 36 deg/h).
const RW_P0_DPS2: f64 = 1e-4;

/// The demo's exact-model Kalman filter (see the file's docs).
#[derive(Parser, Debug)]
struct Args {
    /// The demo's summary.json (`host-sim demo --report DIR`): per-vehicle rows compared.
    #[arg(long)]
    summary: Option<PathBuf>,
    /// Test vehicles (the demo's 32).
    #[arg(long, default_value_t = 32)]
    vehicles: u64,
}

/// States of the exact model's filter at most: the turn-on, the flicker bank's processes,
/// the rate random walk, the Gauss-Markov term (absent ones stay 0: no variance, no noise).
const MAX_STATES: usize = 24;

/// Every state observed with weight 1: the drift is their sum.
const SUM: [f64; MAX_STATES] = [1.0; MAX_STATES];

fn main() -> Result<()> {
    let args = Args::parse();
    let duration_s = 1800.0;
    let summary: Option<Value> = match &args.summary {
        Some(p) => Some(
            serde_json::from_str(
                &std::fs::read_to_string(p).with_context(|| format!("{}", p.display()))?,
            )
            .with_context(|| format!("{}: not JSON", p.display()))?,
        ),
        None => None,
    };
    let rows = summary
        .as_ref()
        .and_then(|s| s.pointer("/test_set/heading_rms_deg"))
        .and_then(Value::as_array);
    let (mut limit, mut walk) = (Vec::new(), Vec::new());
    // Per-sample drift error RMS, deg/h.
    let (mut e_limit, mut e_walk) = (Vec::new(), Vec::new());
    let (mut below_all, mut below_fog, mut fog_below_all, mut below_walk) = (0, 0, 0, 0);
    for i in 0..args.vehicles {
        let unit = VEHICLE_UNIT + i;
        let seed = VEHICLE_SEED + i;
        let model = family_model(unit, true)?;
        let full = samples(&model, seed, duration_s)?;
        let mut det = model.clone();
        det.noise.arw_dps_per_rthz = 0.0;
        det.noise.bias_instability_dps = 0.0;
        det.noise.rrw_dps_per_s_rthz = 0.0;
        det.noise.gm_sigma_dps = 0.0;
        det.bias.turn_on_sigma_dps = 0.0;
        let det_s = samples(&det, seed, duration_s)?;
        if det_s.len() != full.len()
            || det_s
                .iter()
                .zip(&full)
                .any(|(a, b)| a.true_rate_dps != b.true_rate_dps || a.t_s != b.t_s)
        {
            bail!("vehicle {i}: the deterministic run does not follow the full one");
        }
        let m = realize(&model, seed);
        let n = &m.noise;
        let dt = 1.0 / host_sim::demo::RATE_HZ;
        let (mut phi, mut q, mut p0) = (Vec::new(), Vec::new(), Vec::new());
        // Turn-on's random part: a constant.
        phi.push(1.0);
        q.push(0.0);
        p0.push(m.bias.turn_on_sigma_dps.powi(2));
        if n.bias_instability_dps > 0.0 {
            let times = flicker_times_s(n.flicker_tau_min_s, n.flicker_tau_max_s);
            let var = flicker_unit_var(&times, n.flicker_tau_min_s, n.flicker_tau_max_s)
                * n.bias_instability_dps.powi(2);
            for t in times {
                let f = (-dt / t).exp();
                phi.push(f);
                q.push(var * (1.0 - f * f));
                p0.push(var);
            }
        }
        if n.rrw_dps_per_s_rthz > 0.0 {
            phi.push(1.0);
            q.push(n.rrw_dps_per_s_rthz.powi(2) * dt);
            p0.push(0.0);
        }
        if n.gm_sigma_dps > 0.0 {
            let f = (-dt / n.gm_tau_s).exp();
            phi.push(f);
            q.push(n.gm_sigma_dps.powi(2) * (1.0 - f * f));
            p0.push(n.gm_sigma_dps.powi(2));
        }
        if phi.len() > MAX_STATES {
            bail!("vehicle {i}: {} states, at most {MAX_STATES}", phi.len());
        }
        let mut model_k = DiagonalModel {
            phi: [1.0; MAX_STATES],
            q: [0.0; MAX_STATES],
        };
        let mut p0_k = [0.0; MAX_STATES];
        model_k.phi[..phi.len()].copy_from_slice(&phi);
        model_k.q[..q.len()].copy_from_slice(&q);
        p0_k[..p0.len()].copy_from_slice(&p0);
        let mut kf = Kalman::new([0.0; MAX_STATES], p0_k);
        let r = n.arw_dps_per_rthz.powi(2) / dt + m.quantization.quantum_dps.powi(2) / 12.0;
        let mut est = Vec::with_capacity(full.len());
        for (a, d) in full.iter().zip(&det_s) {
            kf.predict(&model_k);
            if !a.moving {
                kf.update(&SUM, a.rate_dps - a.true_rate_dps - d.drift_dps, r);
            }
            est.push(d.drift_dps + kf.observe(&SUM));
        }
        let rec = NavRecord::from_samples(&full);
        let sc = nav::score_drift(&rec, &est);
        let h = sc.heading_rms_deg;
        limit.push(h);
        e_limit.push(sc.e_truth_dph.unwrap_or(f64::NAN));
        // The random walk of the demo's baseline q on the same measurements.
        let walk_model = DiagonalModel {
            phi: [1.0],
            q: [RW_Q_DPS2],
        };
        let mut rw = Kalman::new([0.0], [RW_P0_DPS2]);
        let mut rw_est = Vec::with_capacity(full.len());
        for a in &full {
            rw.predict(&walk_model);
            if !a.moving {
                rw.update(&[1.0], a.rate_dps - a.true_rate_dps, RW_R_DPS2);
            }
            rw_est.push(rw.x()[0]);
        }
        let sc_rw = nav::score_drift(&rec, &rw_est);
        let h_rw = sc_rw.heading_rms_deg;
        walk.push(h_rw);
        e_walk.push(sc_rw.e_truth_dph.unwrap_or(f64::NAN));
        below_walk += usize::from(h < h_rw);
        let line = rows
            .and_then(|r| r.get(i as usize))
            .and_then(Value::as_array);
        if let Some(line) = line {
            let vals: Vec<(String, f64)> = line
                .iter()
                .filter_map(|x| {
                    let a = x.as_array()?;
                    Some((a.first()?.as_str()?.to_string(), a.get(1)?.as_f64()?))
                })
                .collect();
            let fog = vals.first().map_or(f64::NAN, |v| v.1);
            let best = vals
                .iter()
                .skip(1)
                .filter(|v| v.0 != "no compensation")
                .map(|v| v.1)
                .fold(f64::INFINITY, f64::min);
            below_all += usize::from(h < best);
            below_fog += usize::from(h < fog);
            fog_below_all += usize::from(fog < best);
            println!(
                "vehicle {i:2} (unit {unit}, seed {seed}): exact model {h:.4} random walk {h_rw:.4} fog {fog:.4} best baseline {best:.4}"
            );
        } else {
            println!(
                "vehicle {i:2} (unit {unit}, seed {seed}): exact model {h:.4} random walk {h_rw:.4}"
            );
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "mean heading RMS over {n} vehicles, truth flags: the exact model's Kalman filter {:.4} deg, the random walk (q {RW_Q_DPS2:.0e}) {:.4}; the exact model below the random walk on {below_walk}",
        mean(&limit),
        mean(&walk),
        n = limit.len()
    );
    println!(
        "mean drift error RMS per sample (e_truth): the exact model {:.3} deg/h, the random walk {:.3}",
        mean(&e_limit),
        mean(&e_walk)
    );
    if rows.is_some() {
        println!(
            "the exact model below every baseline of the demo on {below_all} of {n}, below fog on {below_fog}; fog below every baseline on {fog_below_all}",
            n = limit.len()
        );
    }
    Ok(())
}
