//! Causal baselines on vehicle records of a gyro family, from BOTH generators:
//! `cargo run --release -p host-sim --example nav_baselines [-- OUT_DIR]`
//!
//! - host-sim simulator: E-Core 2000 preset, `[family] unit_spread = 0.2` with per-record
//!   temperature conditions, `[motion] profile = "vehicle"`, 1800 s at 100 Hz. Thermal
//!   coefficients fitted on 12 static training records (units 1..12); the gated Kalman's q
//!   tuned on 3 validation vehicle records (units 21..23); scored on 4 test vehicle records
//!   (units 31..34). Still flags = the truth (`!moving`): the baselines' best case.
//! - scripts/gen_nav_records.py (when python3 + numpy are present): the same protocol on
//!   its records, nominal family and `--ood` (wide parameter draws).
//!
//! Prints heading-error RMS / final (deg) and e_truth still / moving (deg/h), mean over the
//! test records. With OUT_DIR, writes the heading-error SVG of the first test record.

use anyhow::{bail, Result};
use host_sim::nav::{
    fit_thermal, log_grid, run, tune_gated_q, AlignmentBias, DriftEstimator, GatedKalman,
    NavRecord, NoCompensation, ThermalKalman, ThermalKalmanConfig,
};
use host_sim::report::{heading_error_svg, still_spans, HeadingSeries};
use host_sim::sim::{self, Model, Simulator};
use std::path::{Path, PathBuf};
use std::process::Command;

const DURATION_S: f64 = 1800.0;

fn family_model(vehicle: bool) -> Result<Model> {
    let mut m = sim::preset("ecore2000")?;
    m.family.unit_spread = 0.2;
    m.family.initial_c_range = Some([10.0, 35.0]);
    m.family.warmup_rise_c_range = Some([2.0, 8.0]);
    m.family.ramp_c_per_s_range = Some([-5.0 / 3600.0, 5.0 / 3600.0]);
    if vehicle {
        m.motion.profile = sim::Profile::Vehicle;
    }
    Ok(m)
}

fn ours(vehicle: bool, unit: u64, seed: u64) -> Result<NavRecord> {
    let mut m = family_model(vehicle)?;
    m.family.unit_seed = Some(unit);
    let mut s = Simulator::new(&m, seed, 100.0)?;
    let n = (DURATION_S * 100.0) as usize;
    let v: Vec<_> = (0..n).map(|_| s.next_sample()).collect();
    Ok(NavRecord::from_samples(&v))
}

/// (record, white-noise variance per sample) from the Python generator.
fn theirs(dir: &Path, kind: &str, unit: u64, seed: u64, ood: bool) -> Result<(NavRecord, f64)> {
    let out = dir.join(format!("{kind}_{unit}_{seed}_{ood}.csv"));
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scripts/gen_nav_records.py");
    let mut c = Command::new("python3");
    c.arg(script)
        .args(["--kind", kind, "--seed", &seed.to_string()]);
    c.args([
        "--duration-s",
        &DURATION_S.to_string(),
        "--unit-seed",
        &unit.to_string(),
    ]);
    c.args(["--unit-spread", "0.2", "--out"]).arg(&out);
    if ood {
        c.arg("--ood");
    }
    if !c.status()?.success() {
        bail!("gen_nav_records.py failed");
    }
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("csv.json"))?)?;
    let s = &meta["sensor"];
    let f = |k: &str| s[k].as_f64().unwrap_or(0.0);
    let r = (f("arw_deg_rth") / 60.0).powi(2) * f("rate_hz") + f("quantum_dps").powi(2) / 12.0;
    Ok((NavRecord::read(&out)?, r))
}

fn thermal_rows(r: &NavRecord) -> Vec<(f64, f64, f64, bool)> {
    let temp = r.temp_c.clone().unwrap_or_default();
    (0..r.len())
        .map(|k| {
            let z = r.rate_dps[k] - r.true_rate_dps[k];
            (
                r.t_s[k],
                z,
                temp.get(k).copied().unwrap_or(f64::NAN),
                !r.moving[k],
            )
        })
        .collect()
}

struct Set {
    name: String,
    train: Vec<NavRecord>,
    valid: Vec<NavRecord>,
    test: Vec<NavRecord>,
    r_dps2: f64,
}

fn evaluate(set: &Set, svg_dir: Option<&Path>) -> Result<()> {
    let grid = log_grid(1e-16, 1e-8, 2);
    let Some(tuned) = tune_gated_q(&set.valid, set.r_dps2, &grid) else {
        bail!("no tuning");
    };
    let rows: Vec<_> = set.train.iter().map(thermal_rows).collect();
    let cfg = ThermalKalmanConfig {
        q_dps2: tuned.q_dps2,
        r_dps2: set.r_dps2,
        ..ThermalKalmanConfig::default()
    };
    let fit = fit_thermal(&rows, cfg.dtemp_tau_s);
    println!(
        "\n{}: q tuned {:.1e} (deg/s)^2/sample (valid heading RMS {:.4} deg); thermal fit {:?}",
        set.name, tuned.q_dps2, tuned.heading_rms_deg, fit
    );
    println!(
        "{:<28} {:>10} {:>10} {:>12} {:>12}",
        "estimator", "hdg RMS", "|hdg end|", "e still", "e moving"
    );
    type Make = Box<dyn Fn() -> Box<dyn DriftEstimator>>;
    let mut makers: Vec<(&str, Make)> = vec![
        ("none", Box::new(|| Box::new(NoCompensation))),
        (
            "alignment bias",
            Box::new(|| Box::new(AlignmentBias::default())),
        ),
        (
            "gated Kalman (tuned q)",
            Box::new(move || Box::new(GatedKalman::new(tuned.q_dps2, cfg.r_dps2))),
        ),
        (
            "gated Kalman + thermal RLS",
            Box::new(move || Box::new(ThermalKalman::new(cfg))),
        ),
    ];
    if let Some(fit) = fit {
        makers.push((
            "gated Kalman + thermal fit",
            Box::new(move || Box::new(ThermalKalman::with_fit(cfg, fit))),
        ));
    }
    let mut heading = Vec::new();
    for (name, make) in &makers {
        let (mut a, mut b, mut c, mut d) = (0.0, 0.0, 0.0, 0.0);
        for (i, r) in set.test.iter().enumerate() {
            let out = run(r, make().as_mut(), &r.still_truth());
            let s = out.scores;
            a += s.heading_rms_deg;
            b += s.heading_final_deg.abs();
            c += s.e_truth_still_dph.unwrap_or(f64::NAN);
            d += s.e_truth_moving_dph.unwrap_or(f64::NAN);
            if i == 0 {
                heading.push((name.to_string(), out.heading_deg));
            }
        }
        let n = set.test.len() as f64;
        println!(
            "{name:<28} {:>10.4} {:>10.4} {:>12.3} {:>12.3}",
            a / n,
            b / n,
            c / n,
            d / n
        );
    }
    if let Some(dir) = svg_dir {
        let r = &set.test[0];
        let series: Vec<HeadingSeries> = heading
            .iter()
            .map(|(l, h)| HeadingSeries {
                label: l,
                t_s: &r.t_s,
                heading_deg: h,
            })
            .collect();
        let svg = heading_error_svg(
            &format!("Heading error: {}", set.name),
            &series,
            &still_spans(&r.t_s, &r.still_truth()),
        )?;
        let path = dir.join(format!("heading_{}.svg", set.name.replace([' ', '/'], "_")));
        std::fs::write(&path, svg)?;
        println!("-> {}", path.display());
    }
    Ok(())
}

fn main() -> Result<()> {
    let svg_dir = std::env::args().nth(1).map(PathBuf::from);
    let r_dps2 = 0.001_111_11f64.powi(2) * 100.0 + (60.0f64 / 32768.0).powi(2) / 12.0;
    let set = Set {
        name: "host-sim family".into(),
        train: (1..=12)
            .map(|u| ours(false, u, 1000 + u))
            .collect::<Result<_>>()?,
        valid: (21..=23)
            .map(|u| ours(true, u, 2000 + u))
            .collect::<Result<_>>()?,
        test: (31..=34)
            .map(|u| ours(true, u, 3000 + u))
            .collect::<Result<_>>()?,
        r_dps2,
    };
    evaluate(&set, svg_dir.as_deref())?;
    let ok = Command::new("python3")
        .args(["-c", "import numpy"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if !ok {
        println!("\nsecond generator SKIPPED: python3 with numpy not found");
        return Ok(());
    }
    let tmp = tempfile::tempdir()?;
    for ood in [false, true] {
        let get = |kind: &str, u: u64, s: u64| theirs(tmp.path(), kind, u, s, ood);
        let train: Vec<_> = (1..=12)
            .map(|u| get("static", u, 1000 + u))
            .collect::<Result<_>>()?;
        let valid: Vec<_> = (21..=23)
            .map(|u| get("vehicle", u, 2000 + u))
            .collect::<Result<_>>()?;
        let test: Vec<_> = (31..=34)
            .map(|u| get("vehicle", u, 3000 + u))
            .collect::<Result<_>>()?;
        // OOD records differ in rate and noise: r from the first test record's sensor (the
        // nominal-family sets share it).
        let r_dps2 = test[0].1;
        let set = Set {
            name: format!("gen_nav_records{}", if ood { " OOD" } else { "" }),
            train: train.into_iter().map(|x| x.0).collect(),
            valid: valid.into_iter().map(|x| x.0).collect(),
            test: test.into_iter().map(|x| x.0).collect(),
            r_dps2,
        };
        evaluate(&set, svg_dir.as_deref())?;
    }
    Ok(())
}
