//! Probe: the gated flicker-bank filter (parameters from the noise specification) beside
//! the gated RW+GM filter tuned on validation vehicles, truth still flags.
//! `cargo run --release -p host-sim --example bank_probe -- [--ood] [--vehicles N]`
use anyhow::{bail, Result};
use host_sim::nav::{
    log_grid, run, BankConfig, DriftEstimator, GatedBank, GatedRwGm, NavRecord, RwGmConfig,
};
use host_sim::sim::{self, Simulator};
use std::path::{Path, PathBuf};
use std::process::Command;

const DPH: f64 = 1.0 / 3600.0;

fn theirs(dir: &Path, unit: u64, seed: u64, ood: bool) -> Result<(NavRecord, f64)> {
    let out = dir.join(format!("vehicle_{unit}_{seed}_{ood}.csv"));
    if !out.exists() {
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/gen_nav_records.py");
        let mut c = Command::new("python3");
        c.arg(script)
            .args(["--kind", "vehicle", "--seed", &seed.to_string()]);
        c.args(["--duration-s", "1800", "--unit-seed", &unit.to_string()]);
        c.args(["--unit-spread", "0.2", "--out"]).arg(&out);
        if ood {
            c.arg("--ood");
        }
        if !c.status()?.success() {
            bail!("gen failed");
        }
    }
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("csv.json"))?)?;
    let s = &meta["sensor"];
    let f = |k: &str| s[k].as_f64().unwrap_or(0.0);
    let r = (f("arw_deg_rth") / 60.0).powi(2) * f("rate_hz") + f("quantum_dps").powi(2) / 12.0;
    Ok((NavRecord::read(&out)?, r))
}

fn ours(unit: u64, seed: u64) -> Result<(NavRecord, f64)> {
    let mut m = sim::preset("ecore2000")?;
    m.family.unit_spread = 0.2;
    m.family.initial_c_range = Some([10.0, 35.0]);
    m.family.warmup_rise_c_range = Some([2.0, 8.0]);
    m.family.ramp_c_per_s_range = Some([-5.0 / 3600.0, 5.0 / 3600.0]);
    m.motion.profile = sim::Profile::Vehicle;
    m.family.unit_seed = Some(unit);
    let mut s = Simulator::new(&m, seed, 100.0)?;
    let v: Vec<_> = (0..180_000).map(|_| s.next_sample()).collect();
    let r = 0.001_111_11f64.powi(2) * 100.0 + (60.0f64 / 32768.0).powi(2) / 12.0;
    Ok((NavRecord::from_samples(&v), r))
}

fn score(recs: &[(NavRecord, f64)], make: &dyn Fn(f64) -> Box<dyn DriftEstimator>) -> f64 {
    let mut a = 0.0;
    for (r, rr) in recs {
        a += run(r, make(*rr).as_mut(), &r.still_truth())
            .scores
            .heading_rms_deg;
    }
    a / recs.len() as f64
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let ood = args.iter().any(|a| a == "--ood");
    let host = args.iter().any(|a| a == "--host-sim");
    let n: u64 = args
        .iter()
        .skip_while(|a| *a != "--vehicles")
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(16);
    let dir = PathBuf::from("/tmp/bank_probe");
    std::fs::create_dir_all(&dir)?;
    let get = |u: u64, s: u64| {
        if host {
            ours(u, s)
        } else {
            theirs(&dir, u, s, ood)
        }
    };
    let valid: Vec<_> = (100..100 + n)
        .map(|u| get(u, 2000 + u))
        .collect::<Result<_>>()?;
    let test: Vec<_> = (300..300 + n)
        .map(|u| get(u, 3000 + u))
        .collect::<Result<_>>()?;
    let p0 = (30.0 * DPH).powi(2);
    // Spec: B 1.5 deg/h, K 0.5 deg/h/sqrt(h).
    let spec_b = 1.5 * DPH;
    let spec_q = (0.5 * DPH).powi(2) / 3600.0;
    type Make = Box<dyn Fn(f64) -> Box<dyn DriftEstimator>>;
    let bank = |q: f64, b: f64, hi: f64| -> Make {
        Box::new(move |r: f64| -> Box<dyn DriftEstimator> {
            Box::new(GatedBank::new(BankConfig {
                q_rw_dps2_per_s: q,
                b_dps: b,
                tau_min_s: 1.0,
                tau_max_s: hi,
                per_decade: 1.0,
                r_dps2: r,
                p0_dps2: p0,
            }))
        })
    };
    let mut bank_grid: Vec<(String, Make)> = Vec::new();
    for bs in [0.25, 0.5, 1.0, 2.0] {
        for qs in [300.0, 1000.0, 3000.0, 10000.0, 30000.0] {
            for hi in [1000.0, 10000.0] {
                bank_grid.push((
                    format!("bank B x{bs} q x{qs} tau<= {hi}"),
                    bank(spec_q * qs, spec_b * bs, hi),
                ));
            }
        }
    }
    let mut rwgm_grid: Vec<(String, Make)> = Vec::new();
    for q in log_grid(1e-15, 1e-7, 2) {
        for sd in [0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0] {
            for tau in log_grid(1.0, 10000.0, 2) {
                let c = RwGmConfig {
                    q_rw_dps2_per_s: q,
                    sigma_gm_dps: sd * DPH,
                    tau_s: tau,
                    r_dps2: 1.0,
                    p0_dps2: p0,
                };
                rwgm_grid.push((
                    format!("rwgm q {q:.1e} sigma {sd} tau {tau:.0}"),
                    Box::new(move |r| Box::new(GatedRwGm::new(RwGmConfig { r_dps2: r, ..c }))),
                ));
            }
        }
    }
    // Two-fold: tune on one half, per-record scores on the other.
    let per_rec = |recs: &[(NavRecord, f64)], m: &Make| -> Vec<f64> {
        recs.iter()
            .map(|(r, rr)| {
                run(r, m(*rr).as_mut(), &r.still_truth())
                    .scores
                    .heading_rms_deg
            })
            .collect()
    };
    let tune = |recs: &[(NavRecord, f64)], grid: &[(String, Make)]| -> usize {
        let mut best = (0, f64::INFINITY);
        for (i, (_, m)) in grid.iter().enumerate() {
            let v = score(recs, m.as_ref());
            if v < best.1 {
                best = (i, v);
            }
        }
        best.0
    };
    let mut diffs = Vec::new();
    let (mut sb, mut sg) = (0.0, 0.0);
    for (fit, eval) in [(&valid, &test), (&test, &valid)] {
        let ib = tune(fit, &bank_grid);
        let ig = tune(fit, &rwgm_grid);
        let b = per_rec(eval, &bank_grid[ib].1);
        let g = per_rec(eval, &rwgm_grid[ig].1);
        let (mb, mg) = (
            b.iter().sum::<f64>() / b.len() as f64,
            g.iter().sum::<f64>() / g.len() as f64,
        );
        println!(
            "picked {} -> {mb:.4};  {} -> {mg:.4}",
            bank_grid[ib].0, rwgm_grid[ig].0
        );
        sb += mb;
        sg += mg;
        diffs.extend(b.iter().zip(&g).map(|(x, y)| x - y));
    }
    let nd = diffs.len() as f64;
    let md = diffs.iter().sum::<f64>() / nd;
    let sd = (diffs.iter().map(|d| (d - md).powi(2)).sum::<f64>() / (nd - 1.0)).sqrt();
    println!("two-fold mean heading RMS: bank {:.4}, RW+GM {:.4}; paired diff {md:.4} +- {:.4} (se), {} records", sb / 2.0, sg / 2.0, sd / nd.sqrt(), nd);
    Ok(())
}
