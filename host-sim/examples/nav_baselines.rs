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
//! Beside them, the gated RW+GM Kalman filter ([`GatedRwGm`]: slow random walk plus a
//! first-order Gauss-Markov state), its three parameters tuned on the same validation
//! vehicles over [`rwgm_grid`] (a pick at a grid end is marked `GRID END`).
//!
//! Then the firmware's preset `motion` (fog_core::motion), trained on the same 12 static
//! records (3 DRLS passes) and shrunk by leave-one-record-out over them (scored on the
//! held-out records' window-mean changes over 60 windows; alpha and the held-out gains
//! printed; `unshrunk m` rows: the model as trained), its level noise
//! tuned on the same validation vehicles (a pick at an end of the q grid is marked
//! `GRID END`), with ITS OWN detector (no truth): the window-mean level
//! ([`LevelUpdate::Window`], the default), the per-sample level with rollback
//! ([`LevelUpdate::Sample`]), each with or without a Gauss-Markov state
//! ([`fog_core::motion::MotionEstimator::with_gauss_markov`]; `Window` + GM is the "hybrid";
//! the dual: [`Arrangement::Dual`]) whose sigma and
//! tau come from the RW+GM filter tuned on the static validation units (`static-tuned`)
//! or on the validation vehicles (`vehicle-tuned`); an untrained model (the gated level
//! alone); the detector's false-still / missed-still rates. Finally static records (4
//! static test units per set): e_truth of the per-sample random-walk Kalman and RW+GM
//! Kalman (every sample still, parameters tuned on 3 static validation units by e_truth)
//! against `motion` (q tuned the same way, the GM state's sigma and tau from the static
//! RW+GM tuning).
//!
//! `-- --trainers [OUT_DIR]`: instead of the rows above, the bench trainers side by side in
//! one run: the model trained by the paper's DRLS (3 passes, as trained), by least squares
//! with the ridge picked by leave-one-record-out (`fog_core::motion_fit`, what `host-sim
//! identify --preset motion` trains by default), and untrained, each as the dual (the
//! product) and the window level, on vehicles and static records, with the least-squares
//! cross-validation printed, and each row's test score at every other q of the grid
//! (how much the pick from 3 validation vehicles matters). `--host-sim-only`: the first
//! set alone. `--vehicles N`: N validation vehicles (units 100..) and N test vehicles
//! (units 300..) per set instead of 3 and 4.
//! `-- --flags`: instead, the product (dual, `drls-checked` model) and the causal baselines
//! with the SAME still flags, scored twice: every estimator with the truth flags (an
//! external still flag), then every estimator with the product's own detector calls (a
//! gyro-only system); each tunes on the validation vehicles with the flags it is scored
//! with, every filter's white noise from each record's sensor. The product twice: q tuned
//! with the static-tuned GM (the default image's way) and q + GM sigma/tau tuned on the
//! validation vehicles (coordinate descent from two starts: that point and the gated RW+GM
//! filter's (q, GM) tuned with the truth flags). `--python-only`: skip the host-sim set;
//! `--ood-only`: the second generator's `--ood` set alone. `--bank`: the product runs
//! `Arrangement::Bank` (the level as the Allan noise model, fog_core::bank; q and the bank's
//! B and longest tau tuned on the validation vehicles), and the bank alone in f64 joins the
//! rows as an ablation; `--bank-dual` / `--bank-guarded`: the same with
//! `Arrangement::BankDual` / `Arrangement::BankGuarded`. `--truth-only` (with `--flags`):
//! the truth-flag rows alone.
//! `--static-only` (without `--flags`): the static records' rows alone (the bank
//! arrangements among them), no vehicles.
//! The Python records' sensor (rate, noise, quantum) comes from each record's sidecar;
//! the drift bound is the E-Core's 30 deg/h (ASSUMED) for every set.

use anyhow::{bail, Result};
use fog_core::motion::{
    LevelUpdate, MotionConfig, MotionModel, MotionTrainer, Transfer, MOTION_DRLS,
};
use fog_core::motion_fit::NormalEquations;
use fog_core::preset::{Arrangement, GaussMarkov, PresetEstimator};
use fog_core::still::SensorConfig;
use host_sim::motion::{
    describe_least_squares, drls_checked, least_squares_fit, LeastSquaresFit, BANK_B_DPH,
    BANK_TAU_MAX_S, SHRINK_LAG_WINDOWS,
};
use host_sim::nav::{
    fit_thermal, log_grid, run, tune_gated_q, AlignmentBias, BankConfig, DriftEstimator, GatedBank,
    GatedKalman, GatedRwGm, NavRecord, NoCompensation, RwGmConfig, ThermalKalman,
    ThermalKalmanConfig,
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

/// (record, white-noise variance per sample, sensor) from the Python generator.
fn theirs(
    dir: &Path,
    kind: &str,
    unit: u64,
    seed: u64,
    ood: bool,
) -> Result<(NavRecord, f64, SensorConfig)> {
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
    let sensor = SensorConfig {
        full_scale_dps: f("full_scale_dps") as f32,
        quantum_dps: f("quantum_dps") as f32,
        sample_rate_hz: f("rate_hz") as f32,
        noise_density_dps_rthz: (f("arw_deg_rth") / 60.0) as f32,
        drift_bound_dps: SensorConfig::ECORE_2000.drift_bound_dps,
    };
    Ok((NavRecord::read(&out)?, r, sensor))
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

/// RW+GM grid: slow random walk 1e-15 .. 1e-7 (deg/s)^2/s (0.00005 .. 4,666 (deg/h)^2/h),
/// 2 per decade; Gauss-Markov sigma 0.25 .. 16 deg/h, factor 2; tau 1 .. 10,000 s, 2 per
/// decade. [`rwgm_label`] marks a pick at an end of a range.
const SIGMA_DPH: [f64; 7] = [0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0];
const TAU_S: (f64, f64) = (1.0, 10000.0);
const Q_RW: (f64, f64) = (1e-15, 1e-7);

fn rwgm_grid(r_dps2: f64) -> Vec<RwGmConfig> {
    log_grid(Q_RW.0, Q_RW.1, 2)
        .into_iter()
        .flat_map(|q| {
            gm_grid(RwGmConfig {
                q_rw_dps2_per_s: q,
                sigma_gm_dps: 0.0,
                tau_s: 1.0,
                r_dps2,
                p0_dps2: (30.0f64 / 3600.0).powi(2),
            })
        })
        .collect()
}

/// The Gauss-Markov part of [`rwgm_grid`] (sigma, then tau) with the rest of `base`.
fn gm_grid(base: RwGmConfig) -> Vec<RwGmConfig> {
    SIGMA_DPH
        .iter()
        .flat_map(|&sigma_dph| {
            log_grid(TAU_S.0, TAU_S.1, 2)
                .into_iter()
                .map(move |tau_s| RwGmConfig {
                    sigma_gm_dps: sigma_dph / 3600.0,
                    tau_s,
                    ..base
                })
        })
        .collect()
}

fn rwgm_label(c: &RwGmConfig) -> String {
    let end = |v: f64, (lo, hi): (f64, f64)| {
        if (v / lo - 1.0).abs() < 1e-6 || (v / hi - 1.0).abs() < 1e-6 {
            " (GRID END)"
        } else {
            ""
        }
    };
    let sigma_dph = c.sigma_gm_dps * 3600.0;
    format!(
        "q {:.1} (deg/h)^2/h{}, sigma {sigma_dph} deg/h{}, tau {:.0} s{}",
        c.q_rw_dps2_per_s * 3600f64.powi(3),
        end(c.q_rw_dps2_per_s, Q_RW),
        end(sigma_dph, (SIGMA_DPH[0], SIGMA_DPH[SIGMA_DPH.len() - 1])),
        c.tau_s,
        end(c.tau_s, TAU_S)
    )
}

/// The grid point with the least `score` (ties to the first).
fn pick<T: Copy>(grid: &[T], mut score: impl FnMut(&T) -> Result<f64>) -> Result<(T, f64)> {
    let mut best: Option<(T, f64)> = None;
    for c in grid {
        let v = score(c)?;
        if best.as_ref().is_none_or(|b| v < b.1) {
            best = Some((*c, v));
        }
    }
    best.ok_or_else(|| anyhow::anyhow!("empty grid"))
}

struct Set {
    name: String,
    train: Vec<NavRecord>,
    valid: Vec<NavRecord>,
    test: Vec<NavRecord>,
    r_dps2: f64,
    /// Sensor of each train / valid / test record (in that order).
    sensors: Vec<SensorConfig>,
    /// Static records: 3 validation units, 4 test units, each with its sensor.
    static_valid: Vec<(NavRecord, SensorConfig)>,
    static_test: Vec<(NavRecord, SensorConfig)>,
}

/// Returns the RW+GM configuration tuned on the validation vehicles.
fn evaluate(set: &Set, svg_dir: Option<&Path>) -> Result<RwGmConfig> {
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
    let valid_rms = |c: &RwGmConfig| -> Result<f64> {
        let sum: f64 = set
            .valid
            .iter()
            .map(|r| {
                run(r, &mut GatedRwGm::new(*c), &r.still_truth())
                    .scores
                    .heading_rms_deg
            })
            .sum();
        Ok(sum / set.valid.len() as f64)
    };
    let (gm, gm_v) = pick(&rwgm_grid(set.r_dps2), valid_rms)?;
    println!(
        "gated RW+GM tuned: {} (valid heading RMS {gm_v:.4} deg)",
        rwgm_label(&gm)
    );
    makers.push((
        "gated RW+GM Kalman (tuned)",
        Box::new(move || Box::new(GatedRwGm::new(gm))),
    ));
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
    Ok(gm)
}

/// The motion estimator as a [`DriftEstimator`]: its own detector, or the run's still
/// flags as its external flag (`truth`). Keeps its still calls for the detector scores.
/// The "dual" rows run [`Arrangement::Dual`] (fog-core's [`PresetEstimator`], what the
/// firmware runs): the per-sample level + GM beside the window level + GM on the same
/// samples; the output is the per-sample one's drift while it flags the sample still and
/// the window one's otherwise (in motion, and from the first sample the fast gate or the
/// detector flags moving).
struct Motion {
    est: PresetEstimator,
    truth: bool,
    calls: Vec<bool>,
}

impl DriftEstimator for Motion {
    fn name(&self) -> String {
        "motion".into()
    }
    fn push(&mut self, _: f64, rate_dps: f64, temp_c: Option<f64>, still: bool) -> f64 {
        let temp = temp_c.map_or(f32::NAN, |t| t as f32);
        let ext = self.truth.then_some(still);
        match self.est.push(rate_dps as f32, temp, ext) {
            Ok(o) => {
                self.calls.push(o.still);
                f64::from(o.drift_dps)
            }
            Err(_) => {
                self.calls.push(false);
                0.0
            }
        }
    }
}

/// Level noise grid, (deg/h)^2/h: 0.25 .. 16384, 4 per decade (the Kalman's density).
fn q_grid_dph2_per_h() -> Vec<f64> {
    log_grid(0.25, 16384.0, 4)
}

/// ` (GRID END)` when `q` is an end of [`q_grid_dph2_per_h`].
fn q_end(q: f64) -> &'static str {
    let g = q_grid_dph2_per_h();
    let at = |v: Option<&f64>| v.is_some_and(|v| (q / v - 1.0).abs() < 1e-9);
    if at(g.first()) || at(g.last()) {
        " (GRID END)"
    } else {
        ""
    }
}

/// `--bank`, `--bank-dual` or `--bank-guarded`: the `--flags` product runs that bank
/// arrangement instead of the dual.
fn bank_arrangement() -> Option<Arrangement> {
    std::env::args().find_map(|a| match a.as_str() {
        "--bank" => Some(Arrangement::Bank),
        "--bank-dual" => Some(Arrangement::BankDual),
        "--bank-guarded" => Some(Arrangement::BankGuarded),
        _ => None,
    })
}

/// `base` with the bank at the family's specification, `identify`'s default (B
/// [`BANK_B_DPH`] deg/h in sigma, states up to [`BANK_TAU_MAX_S`] s in tau; ASSUMED E-Core
/// class).
fn bank_spec(base: RwGmConfig) -> RwGmConfig {
    RwGmConfig {
        sigma_gm_dps: f64::from(BANK_B_DPH) / 3600.0,
        tau_s: f64::from(BANK_TAU_MAX_S),
        ..base
    }
}

/// `--static-only`: of the default rows, the static records' alone (no vehicles).
fn static_only() -> bool {
    std::env::args().any(|a| a == "--static-only")
}

fn q_dps2_per_s(q_dph2_per_h: f64) -> f32 {
    (q_dph2_per_h / 3600f64.powi(3)) as f32
}

/// The level's second state in a `motion` row.
#[derive(Clone, Copy)]
enum Second {
    None,
    /// Gauss-Markov state with the sigma and tau of this RW+GM configuration.
    Gm(RwGmConfig),
    /// The dual ([`Arrangement::Dual`]): per-sample level + GM at rest, window level + GM
    /// (the hybrid) in motion, both with this configuration's sigma and tau and the row's q
    /// (the row's update is ignored).
    Dual(RwGmConfig),
    /// A bank arrangement ([`Arrangement::is_bank`]): the level as the Allan noise model,
    /// `B` = this configuration's sigma, longest correlation time = its tau, random walk =
    /// the row's q.
    Bank(Arrangement, RwGmConfig),
}

fn motion_est(
    model: &MotionModel,
    sensor: SensorConfig,
    q: f64,
    update: LevelUpdate,
    truth: bool,
    second: Second,
) -> Result<Motion> {
    let mut cfg = MotionConfig::for_sensor(sensor);
    cfg.level_q_dps2_per_s = q_dps2_per_s(q);
    let gm = |c: RwGmConfig| GaussMarkov {
        sigma_dps: c.sigma_gm_dps as f32,
        tau_s: c.tau_s as f32,
    };
    let single = match update {
        LevelUpdate::Window => Arrangement::Window,
        LevelUpdate::Sample => Arrangement::Sample,
    };
    let (arrangement, gm) = match second {
        Second::None => (single, GaussMarkov::OFF),
        Second::Gm(c) => (single, gm(c)),
        Second::Dual(c) => (Arrangement::Dual, gm(c)),
        Second::Bank(a, c) => (a, gm(c)),
    };
    let est = PresetEstimator::new(*model, cfg, arrangement, gm)
        .map_err(|e| anyhow::anyhow!("estimator: {e}"))?;
    Ok(Motion {
        est,
        truth,
        calls: Vec::new(),
    })
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|&x| x as f32).collect()
}

/// 3 DRLS passes over `recs` except record `skip`.
fn train_motion(
    recs: &[NavRecord],
    sensors: &[SensorConfig],
    skip: Option<usize>,
) -> Result<MotionModel> {
    let model = MotionModel::standard(DURATION_S as f32).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut tr = MotionTrainer::new(model, MOTION_DRLS, 1.0).map_err(|e| anyhow::anyhow!("{e}"))?;
    for _ in 0..3 {
        for (i, (r, s)) in recs.iter().zip(sensors).enumerate() {
            if Some(i) == skip {
                continue;
            }
            let temp = r.temp_c.as_deref().map(f32s);
            tr.train_record(&f32s(&r.rate_dps), temp.as_deref(), s.sample_rate_hz)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
    }
    Ok(*tr.model())
}

/// Least squares over all `recs` (within-record centred), ridge by leave-one-record-out
/// (`fog_core::motion_fit`); prints the cross-validation.
fn train_least_squares(recs: &[NavRecord], sensors: &[SensorConfig]) -> Result<MotionModel> {
    let (model, fit) = least_squares(recs, sensors)?;
    println!(
        "{} static records: {}",
        recs.len(),
        describe_least_squares(&fit)
    );
    Ok(model)
}

/// The least-squares model of `recs` and its cross-validation
/// ([`host_sim::motion::least_squares_fit`], as `identify` fits it).
fn least_squares(
    recs: &[NavRecord],
    sensors: &[SensorConfig],
) -> Result<(MotionModel, LeastSquaresFit)> {
    let layout = MotionModel::standard(DURATION_S as f32).map_err(|e| anyhow::anyhow!("{e}"))?;
    let eqs = recs
        .iter()
        .zip(sensors)
        .map(|(r, s)| {
            let temp = r.temp_c.as_deref().map(f32s);
            let rate = f32s(&r.rate_dps);
            NormalEquations::from_record(&layout, &rate, temp.as_deref(), s.sample_rate_hz, 1.0)
                .map(|(e, _)| e)
                .map_err(|e| anyhow::anyhow!("{e}"))
        })
        .collect::<Result<Vec<_>>>()?;
    least_squares_fit(&eqs, DURATION_S as f32)
}

/// The model trained on all `recs` and the same shrunk by leave-one-record-out
/// ([`Transfer`] over changes across [`SHRINK_LAG_WINDOWS`] windows, as `host-sim
/// identify --preset motion` does); prints alpha and the held-out gains, and the alpha the
/// whole record's centred shape (lag 0) would give.
fn train_shrunk(
    recs: &[NavRecord],
    sensors: &[SensorConfig],
) -> Result<(MotionModel, MotionModel)> {
    let full = train_motion(recs, sensors, None)?;
    let (mut cv, mut whole) = (Transfer::default(), Transfer::default());
    let mut each = Vec::new();
    for (i, (r, s)) in recs.iter().zip(sensors).enumerate() {
        let m = train_motion(recs, sensors, Some(i))?;
        let temp = r.temp_c.as_deref().map(f32s);
        let rate = f32s(&r.rate_dps);
        let e = |e| anyhow::anyhow!("{e}");
        let fs = s.sample_rate_hz;
        let one = cv
            .add_record(&m, &rate, temp.as_deref(), fs, 1.0, SHRINK_LAG_WINDOWS)
            .map_err(e)?;
        whole
            .add_record(&m, &rate, temp.as_deref(), fs, 1.0, 0)
            .map_err(e)?;
        each.push(format!("{:.0}", 100.0 * one.gain(1.0)));
    }
    let alpha = cv.alpha();
    println!(
        "shrinkage (leave-one-record-out over {} static records, changes over {SHRINK_LAG_WINDOWS} windows): alpha {alpha:.3}, held-out gain {:.1} % (unscaled {:.1} %; per record unscaled, %: {}); whole-record shape: alpha {:.3}, gain {:.1} %",
        recs.len(),
        100.0 * cv.gain(alpha),
        100.0 * cv.gain(1.0),
        each.join(" "),
        whole.alpha(),
        100.0 * whole.gain(whole.alpha())
    );
    Ok((full.scaled(alpha), full))
}

/// Pooled e_truth (RMS(estimate - truth) / RMS(truth)) from 10 s on, every sample still.
fn e_truth(
    recs: &[(NavRecord, SensorConfig)],
    mut make: impl FnMut(&SensorConfig) -> Result<Box<dyn DriftEstimator>>,
) -> Result<f64> {
    let (mut se, mut st) = (0.0, 0.0);
    for (r, s) in recs {
        let mut est = make(s)?;
        let out = run(r, est.as_mut(), &vec![true; r.len()]);
        let skip = (10.0 * f64::from(s.sample_rate_hz)) as usize;
        for (d, t) in out.drift_est_dps.iter().zip(&r.drift_dps).skip(skip) {
            se += (d - t).powi(2);
            st += t * t;
        }
    }
    Ok((se / st).sqrt())
}

fn sample_var(s: &SensorConfig) -> f64 {
    f64::from(s.sample_var_dps2())
}

/// The gated RW+GM filter with `c`, its white noise from each record's sensor.
fn rwgm(c: RwGmConfig) -> impl Fn(&SensorConfig) -> Result<Box<dyn DriftEstimator>> {
    move |s: &SensorConfig| -> Result<Box<dyn DriftEstimator>> {
        Ok(Box::new(GatedRwGm::new(RwGmConfig {
            r_dps2: sample_var(s),
            ..c
        })))
    }
}

/// Prints one static row: `model` as `update` / `second`, q tuned by e_truth on the static
/// validation units, e_truth on the static test units against the RW Kalman's `k_test`.
fn static_motion_row(
    set: &Set,
    name: &str,
    model: &MotionModel,
    update: LevelUpdate,
    second: Second,
    k_test: f64,
) -> Result<()> {
    let mk = |q: f64| {
        move |s: &SensorConfig| -> Result<Box<dyn DriftEstimator>> {
            Ok(Box::new(motion_est(model, *s, q, update, false, second)?))
        }
    };
    let mut best = (f64::INFINITY, 0.0);
    for q in q_grid_dph2_per_h() {
        let v = e_truth(&set.static_valid, mk(q))?;
        if v < best.0 {
            best = (v, q);
        }
    }
    let t = e_truth(&set.static_test, mk(best.1))?;
    println!(
        "static: {name:<36} (q {:.1} (deg/h)^2/h{}) e_truth {t:.4} ({:+.1} % vs Kalman)",
        best.1,
        q_end(best.1),
        100.0 * (t / k_test - 1.0)
    );
    Ok(())
}

/// The per-sample random-walk Kalman filter with q tuned by e_truth on the static
/// validation units: (q, e_truth on the static test units).
fn static_kalman(set: &Set) -> Result<(f64, f64)> {
    let kalman = |q: f64| {
        move |s: &SensorConfig| -> Result<Box<dyn DriftEstimator>> {
            Ok(Box::new(GatedKalman::new(q, sample_var(s))))
        }
    };
    let mut kbest = (f64::INFINITY, 0.0);
    for q in log_grid(1e-16, 1e-8, 4) {
        let v = e_truth(&set.static_valid, kalman(q))?;
        if v < kbest.0 {
            kbest = (v, q);
        }
    }
    Ok((kbest.1, e_truth(&set.static_test, kalman(kbest.1))?))
}

fn evaluate_motion(set: &Set, gm_vehicle: RwGmConfig, trainers: bool) -> Result<()> {
    let nt = set.train.len();
    let nv = set.valid.len();
    let (s_train, rest) = set.sensors.split_at(nt);
    let (s_valid, s_test) = rest.split_at(nv);
    if std::env::args().any(|a| a == "--flags") {
        return evaluate_flags(set, s_train, s_valid, s_test);
    }
    if trainers {
        return evaluate_trainers(set, s_train, s_valid, s_test);
    }
    let (trained, unshrunk) = train_shrunk(&set.train, s_train)?;
    let untrained = MotionModel::standard(DURATION_S as f32).map_err(|e| anyhow::anyhow!("{e}"))?;
    let score = |model: &MotionModel,
                 recs: &[NavRecord],
                 sensors: &[SensorConfig],
                 q: f64,
                 (update, truth, second): (LevelUpdate, bool, Second)|
     -> Result<(f64, f64, f64, f64, f64)> {
        let (mut a, mut b, mut fs, mut ms) = (0.0, 0.0, 0.0, 0.0);
        let mut e = 0.0;
        for (r, s) in recs.iter().zip(sensors) {
            let mut m = motion_est(model, *s, q, update, truth, second)?;
            let out = run(r, &mut m, &r.still_truth());
            a += out.scores.heading_rms_deg;
            b += out.scores.heading_final_deg.abs();
            e += out.scores.e_truth_moving_dph.unwrap_or(f64::NAN);
            let mut d = host_sim::nav::DetectorAcc::default();
            for (mv, c) in r.moving.iter().zip(&m.calls) {
                d.push(*mv, *c);
            }
            let d = d.scores();
            fs += d.false_still_rate.unwrap_or(f64::NAN);
            ms += d.missed_still_rate.unwrap_or(f64::NAN);
        }
        let n = recs.len() as f64;
        Ok((a / n, b / n, e / n, fs / n, ms / n))
    };
    println!(
        "{:<42} {:>8} {:>10} {:>10} {:>10} {:>9} {:>9}",
        "motion preset", "q dph2/h", "hdg RMS", "|hdg end|", "e moving", "false-st", "missed-st"
    );
    use LevelUpdate::{Sample, Window};
    // The GM state tuned on the static validation units (the product's: one sigma and
    // tau from the bias instability at rest).
    let (gm, _) = pick(&rwgm_grid(1.0), |c| e_truth(&set.static_valid, rwgm(*c)))?;
    let gmv = Second::Gm(gm_vehicle);
    let gms = Second::Gm(gm);
    let vehicle_rows = if static_only() {
        Vec::new()
    } else {
        vec![
            (
                "motion, window update",
                &trained,
                (Window, false, Second::None),
            ),
            (
                "unshrunk m, window update",
                &unshrunk,
                (Window, false, Second::None),
            ),
            (
                "motion, sample + rollback",
                &trained,
                (Sample, false, Second::None),
            ),
            (
                "motion, sample + GM (static-tuned)",
                &trained,
                (Sample, false, gms),
            ),
            (
                "unshrunk m, sample + GM (static-tuned)",
                &unshrunk,
                (Sample, false, gms),
            ),
            (
                "motion, hybrid window + GM (static-tuned)",
                &trained,
                (Window, false, gms),
            ),
            (
                "motion, hybrid window + GM (vehicle-tuned)",
                &trained,
                (Window, false, gmv),
            ),
            (
                "unshrunk m, hybrid window + GM (static)",
                &unshrunk,
                (Window, false, gms),
            ),
            (
                "motion, dual sample+GM / hybrid (static)",
                &trained,
                (Window, false, Second::Dual(gm)),
            ),
            (
                "unshrunk m, dual (static)",
                &unshrunk,
                (Window, false, Second::Dual(gm)),
            ),
            (
                "untrained m, dual (static)",
                &untrained,
                (Window, false, Second::Dual(gm)),
            ),
            (
                "untrained m, window update",
                &untrained,
                (Window, false, Second::None),
            ),
            (
                "untrained m, hybrid window + GM (static)",
                &untrained,
                (Window, false, gms),
            ),
            (
                "untrained m, sample + rollback",
                &untrained,
                (Sample, false, Second::None),
            ),
        ]
    };
    for (name, model, mode) in vehicle_rows {
        let mut best = (f64::INFINITY, 0.0);
        for q in q_grid_dph2_per_h() {
            let v = score(model, &set.valid, s_valid, q, mode)?.0;
            if v < best.0 {
                best = (v, q);
            }
        }
        let (a, b, e, fs, ms) = score(model, &set.test, s_test, best.1, mode)?;
        println!(
            "{name:<42} {:>8.1} {a:>10.4} {b:>10.4} {e:>10.3} {:>8.2}% {:>8.2}%{}",
            best.1,
            100.0 * fs,
            100.0 * ms,
            q_end(best.1)
        );
    }
    // Static records.
    let (k_q, k_test) = static_kalman(set)?;
    println!(
        "static: per-sample RW Kalman (q {k_q:.2e} (deg/s)^2/sample, tuned by e_truth) e_truth {k_test:.4}"
    );
    // The bank arrangements at the family's specification; q tuned as every motion row's.
    let bank_spec = bank_spec(gm);
    let t = e_truth(&set.static_test, rwgm(gm))?;
    println!(
        "static: per-sample RW+GM Kalman ({}) e_truth {t:.4} ({:+.1} % vs Kalman)",
        rwgm_label(&gm),
        100.0 * (t / k_test - 1.0)
    );
    for (name, model, (update, second)) in [
        ("motion, window update", &trained, (Window, Second::None)),
        (
            "unshrunk m, window update",
            &unshrunk,
            (Window, Second::None),
        ),
        (
            "motion, sample + rollback",
            &trained,
            (Sample, Second::None),
        ),
        ("motion, sample + GM", &trained, (Sample, gms)),
        ("unshrunk m, sample + GM", &unshrunk, (Sample, gms)),
        ("motion, hybrid window + GM", &trained, (Window, gms)),
        ("unshrunk m, hybrid window + GM", &unshrunk, (Window, gms)),
        ("untrained m, hybrid window + GM", &untrained, (Window, gms)),
        ("motion, dual", &trained, (Window, Second::Dual(gm))),
        ("unshrunk m, dual", &unshrunk, (Window, Second::Dual(gm))),
        (
            "unshrunk m, bank",
            &unshrunk,
            (Window, Second::Bank(Arrangement::Bank, bank_spec)),
        ),
        (
            "unshrunk m, bank-guarded",
            &unshrunk,
            (Window, Second::Bank(Arrangement::BankGuarded, bank_spec)),
        ),
        (
            "untrained m, sample + rollback",
            &untrained,
            (Sample, Second::None),
        ),
    ] {
        static_motion_row(set, name, model, update, second, k_test)?;
    }
    Ok(())
}

fn main() -> Result<()> {
    let trainers = std::env::args().any(|a| a == "--trainers");
    let flags = std::env::args().any(|a| a == "--flags");
    let python_only = std::env::args().any(|a| a == "--python-only");
    let svg_dir = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with("--") && a.parse::<u64>().is_err())
        .map(PathBuf::from);
    let r_dps2 = 0.001_111_11f64.powi(2) * 100.0 + (60.0f64 / 32768.0).powi(2) / 12.0;
    let ecore = SensorConfig::ECORE_2000;
    let static_ours = |units: std::ops::RangeInclusive<u64>| -> Result<Vec<_>> {
        units
            .map(|u| Ok((ours(false, u, 4000 + u)?, ecore)))
            .collect()
    };
    // Vehicle units: 3 validation (21..23) and 4 test (31..34), or with `--vehicles N`, N
    // of each (validation 100.., test 300..).
    let n_vehicles: Option<u64> = std::env::args()
        .skip_while(|a| a != "--vehicles")
        .nth(1)
        .and_then(|v| v.parse().ok());
    let (valid_units, test_units) = match n_vehicles {
        Some(n) if n > 0 => (100..=99 + n, 300..=299 + n),
        _ => (21..=23, 31..=34),
    };
    let set = Set {
        name: "host-sim family".into(),
        train: (1..=12)
            .map(|u| ours(false, u, 1000 + u))
            .collect::<Result<_>>()?,
        valid: valid_units
            .clone()
            .map(|u| ours(true, u, 2000 + u))
            .collect::<Result<_>>()?,
        test: test_units
            .clone()
            .map(|u| ours(true, u, 3000 + u))
            .collect::<Result<_>>()?,
        r_dps2,
        sensors: vec![ecore; 12 + valid_units.clone().count() + test_units.clone().count()],
        static_valid: static_ours(41..=43)?,
        static_test: static_ours(51..=54)?,
    };
    if !python_only {
        let gm = if flags || static_only() {
            rwgm_grid(1.0)[0] // unused by --flags and the static rows
        } else {
            evaluate(&set, svg_dir.as_deref())?
        };
        evaluate_motion(&set, gm, trainers)?;
    }
    let ok = Command::new("python3")
        .args(["-c", "import numpy"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    if std::env::args().any(|a| a == "--host-sim-only") {
        return Ok(());
    }
    if !ok {
        println!("\nsecond generator SKIPPED: python3 with numpy not found");
        return Ok(());
    }
    let tmp = tempfile::tempdir()?;
    // `--ood-only`: the second generator's `--ood` set alone.
    let ood_only = std::env::args().any(|a| a == "--ood-only");
    for ood in [false, true] {
        if ood_only && !ood {
            continue;
        }
        let get = |kind: &str, u: u64, s: u64| theirs(tmp.path(), kind, u, s, ood);
        let train: Vec<_> = (1..=12)
            .map(|u| get("static", u, 1000 + u))
            .collect::<Result<_>>()?;
        let valid: Vec<_> = valid_units
            .clone()
            .map(|u| get("vehicle", u, 2000 + u))
            .collect::<Result<_>>()?;
        let test: Vec<_> = test_units
            .clone()
            .map(|u| get("vehicle", u, 3000 + u))
            .collect::<Result<_>>()?;
        let stat = |units: std::ops::RangeInclusive<u64>| -> Result<Vec<_>> {
            units
                .map(|u| get("static", u, 4000 + u).map(|x| (x.0, x.2)))
                .collect()
        };
        // OOD records differ in rate and noise: the baselines' r from the first test
        // record's sensor (the nominal-family sets share it); motion uses each record's.
        let r_dps2 = test[0].1;
        let sensors = train
            .iter()
            .chain(&valid)
            .chain(&test)
            .map(|x| x.2)
            .collect();
        let set = Set {
            name: format!("gen_nav_records{}", if ood { " OOD" } else { "" }),
            train: train.into_iter().map(|x| x.0).collect(),
            valid: valid.into_iter().map(|x| x.0).collect(),
            test: test.into_iter().map(|x| x.0).collect(),
            r_dps2,
            sensors,
            static_valid: stat(41..=43)?,
            static_test: stat(51..=54)?,
        };
        let gm = if flags {
            rwgm_grid(1.0)[0] // unused by --flags
        } else {
            evaluate(&set, svg_dir.as_deref())?
        };
        evaluate_motion(&set, gm, trainers)?;
    }
    Ok(())
}

/// `--trainers`: DRLS vs least squares vs untrained, each as the dual and the window level;
/// q tuned on the validation vehicles (vehicle rows) or the static validation units
/// (static rows), GM from the RW+GM filter tuned on the static validation units.
fn evaluate_trainers(
    set: &Set,
    s_train: &[SensorConfig],
    s_valid: &[SensorConfig],
    s_test: &[SensorConfig],
) -> Result<()> {
    let drls = train_motion(&set.train, s_train, None)?;
    let ls = train_least_squares(&set.train, s_train)?;
    let untrained = MotionModel::standard(DURATION_S as f32).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (gm, _) = pick(&rwgm_grid(1.0), |c| e_truth(&set.static_valid, rwgm(*c)))?;
    let rows = [
        ("DRLS m (paper trainer), dual", &drls, Second::Dual(gm)),
        ("least-squares m, dual", &ls, Second::Dual(gm)),
        ("untrained m, dual", &untrained, Second::Dual(gm)),
        ("DRLS m (paper trainer), window", &drls, Second::None),
        ("least-squares m, window", &ls, Second::None),
        ("untrained m, window", &untrained, Second::None),
    ];
    let vehicle = |model: &MotionModel,
                   recs: &[NavRecord],
                   sensors: &[SensorConfig],
                   q: f64,
                   second: Second|
     -> Result<(f64, f64)> {
        let (mut a, mut b) = (0.0, 0.0);
        for (r, s) in recs.iter().zip(sensors) {
            let mut m = motion_est(model, *s, q, LevelUpdate::Window, false, second)?;
            let out = run(r, &mut m, &r.still_truth());
            a += out.scores.heading_rms_deg;
            b += out.scores.heading_final_deg.abs();
        }
        let n = recs.len() as f64;
        Ok((a / n, b / n))
    };
    println!(
        "{:<36} {:>8} {:>10} {:>10}",
        "vehicles (own detector)", "q dph2/h", "hdg RMS", "|hdg end|"
    );
    for (name, model, second) in rows {
        let mut best = (f64::INFINITY, 0.0);
        for q in q_grid_dph2_per_h() {
            let v = vehicle(model, &set.valid, s_valid, q, second)?.0;
            if v < best.0 {
                best = (v, q);
            }
        }
        let (a, b) = vehicle(model, &set.test, s_test, best.1, second)?;
        println!(
            "{name:<36} {:>8.1} {a:>10.4} {b:>10.4}{}",
            best.1,
            q_end(best.1)
        );
        // How much the pick from 3 validation vehicles matters: test score by q.
        let sweep = q_grid_dph2_per_h()
            .into_iter()
            .step_by(2)
            .map(|q| {
                let v = vehicle(model, &set.test, s_test, q, second)?.0;
                Ok(format!("{q:.0}:{v:.4}"))
            })
            .collect::<Result<Vec<_>>>()?;
        println!("    test RMS by q: {}", sweep.join(" "));
    }
    let (_, k_test) = static_kalman(set)?;
    let t = e_truth(&set.static_test, rwgm(gm))?;
    println!(
        "static: per-sample RW Kalman e_truth {k_test:.4}; RW+GM Kalman ({}) {t:.4} ({:+.1} %)",
        rwgm_label(&gm),
        100.0 * (t / k_test - 1.0)
    );
    for (name, model, second) in rows {
        static_motion_row(set, name, model, LevelUpdate::Window, second, k_test)?;
    }
    Ok(())
}

/// The still flags a run gives every estimator: the truth (`!moving`) or the product's own
/// detector calls (at its q picked on the validation vehicles).
struct Flags<'a> {
    name: &'a str,
    valid: Vec<Vec<bool>>,
    test: Vec<Vec<bool>>,
    /// The gated RW+GM filter already tuned on `valid` (the truth flags' is).
    rwgm: Option<RwGmConfig>,
}

/// `--flags`: the product and the causal baselines, each with the SAME still flags: the
/// truth (an external still flag, e.g. from wheel speed) or the product's own detector
/// (what a gyro-only system has). Every estimator tunes on the validation vehicles with
/// the flags it is scored with; the white-noise variance of every filter is each record's
/// sensor's. The product: the default image's arrangement (dual, GM from the static RW+GM
/// tuning) with the default trainer's model (`drls-checked`).
fn evaluate_flags(
    set: &Set,
    s_train: &[SensorConfig],
    s_valid: &[SensorConfig],
    s_test: &[SensorConfig],
) -> Result<()> {
    let (ls, fit) = least_squares(&set.train, s_train)?;
    let model = drls_checked(train_motion(&set.train, s_train, None)?, &fit, &ls);
    println!(
        "\n{} (--flags): the default's check {}",
        set.name,
        if model.weights.iter().any(|w| *w != 0.0) {
            "keeps DRLS's model"
        } else {
            "empties the model"
        }
    );
    let (gm, _) = pick(&rwgm_grid(1.0), |c| e_truth(&set.static_valid, rwgm(*c)))?;
    // `--bank`: the product's level is the Allan noise model; its start is the family's
    // specification.
    let bank = bank_arrangement().is_some();
    let gm = if bank { bank_spec(gm) } else { gm };
    // Product: mean heading RMS and |end| over `recs`, with each record's still calls.
    let product = |recs: &[NavRecord],
                   sensors: &[SensorConfig],
                   q: f64,
                   gm: RwGmConfig,
                   truth: bool|
     -> Result<(f64, f64, Vec<Vec<bool>>)> {
        let (mut a, mut b, mut calls) = (0.0, 0.0, Vec::new());
        for (r, s) in recs.iter().zip(sensors) {
            let second = if let Some(a) = bank_arrangement() {
                Second::Bank(a, gm)
            } else {
                Second::Dual(gm)
            };
            let mut m = motion_est(&model, *s, q, LevelUpdate::Window, truth, second)?;
            let out = run(r, &mut m, &r.still_truth());
            a += out.scores.heading_rms_deg;
            b += out.scores.heading_final_deg.abs();
            calls.push(m.calls);
        }
        let n = recs.len() as f64;
        Ok((a / n, b / n, calls))
    };
    println!(
        "{:<34} {:<9} {:>10} {:>10}  picked on validation",
        "estimator", "flags", "hdg RMS", "|hdg end|"
    );
    let mut flag_sets = Vec::new();
    let bank_grid: Vec<RwGmConfig> = [0.375, 0.75, 1.5, 3.0]
        .iter()
        .flat_map(|&b_dph| {
            [1000.0, 10_000.0].map(move |tau_s| RwGmConfig {
                sigma_gm_dps: b_dph / 3600.0,
                tau_s,
                ..gm
            })
        })
        .collect();
    let gm_grid = gm_grid(gm);
    // Mean heading RMS and |end| of `make(sensor)` over `recs` with `flags`.
    let score = |recs: &[NavRecord],
                 sensors: &[SensorConfig],
                 flags: &[Vec<bool>],
                 make: &dyn Fn(&SensorConfig) -> Result<Box<dyn DriftEstimator>>|
     -> Result<(f64, f64)> {
        let (mut a, mut b) = (0.0, 0.0);
        for ((r, s), fl) in recs.iter().zip(sensors).zip(flags) {
            let out = run(r, make(s)?.as_mut(), fl);
            a += out.scores.heading_rms_deg;
            b += out.scores.heading_final_deg.abs();
        }
        let n = recs.len() as f64;
        Ok((a / n, b / n))
    };
    // The gated RW+GM filter tuned on the validation vehicles with `flags`.
    let tune_rwgm = |flags: &[Vec<bool>]| -> Result<RwGmConfig> {
        Ok(pick(&rwgm_grid(1.0), |c| {
            Ok(score(&set.valid, s_valid, flags, &rwgm(*c))?.0)
        })?
        .0)
    };
    let truth_valid: Vec<Vec<bool>> = set.valid.iter().map(|r| r.still_truth()).collect();
    // Tuned with the truth flags: a second start for the product's (q, GM) search (its GM
    // may revert slowly to the level), and the truth rows' RW+GM baseline.
    let rwgm_truth = tune_rwgm(&truth_valid)?;
    // Its random walk on the product's q grid (the nearest point in log).
    let q_grid = q_grid_dph2_per_h();
    let q_rw = rwgm_truth.q_rw_dps2_per_s * 3600f64.powi(3);
    let (q_start, _) = pick(&q_grid, |q| Ok((q / q_rw).ln().abs()))?;
    // `--truth-only`: the external-flag half alone.
    let truth_only = std::env::args().any(|a| a == "--truth-only");
    for truth in [true, false] {
        if truth_only && !truth {
            continue;
        }
        let name = if truth { "truth" } else { "detector" };
        let valid = |q: f64, g: RwGmConfig| Ok(product(&set.valid, s_valid, q, g, truth)?.0);
        // q with the static-tuned GM (the default image's way), then (q, GM) on the
        // validation vehicles by coordinate descent (GM at q, q at GM, twice) from two
        // starts: that point and the tuned RW+GM filter's (q, GM); the better end is kept.
        let (q0, _) = pick(&q_grid, |q| valid(*q, gm))?;
        let mut ends = Vec::new();
        let starts = if bank {
            vec![(q0, gm)]
        } else {
            vec![(q0, gm), (q_start, rwgm_truth)]
        };
        for (q_init, g_init) in starts {
            let (mut q, mut g) = (q_init, g_init);
            for _ in 0..2 {
                g = pick(if bank { &bank_grid } else { &gm_grid }, |c| valid(q, *c))?.0;
                q = pick(&q_grid, |q| valid(*q, g))?.0;
            }
            ends.push((q, g));
        }
        let ((q, g), valid_rms) = pick(&ends, |(q, g)| valid(*q, *g))?;
        let (a, b, _) = product(&set.test, s_test, q0, gm, truth)?;
        println!(
            "{:<34} {name:<9} {a:>10.4} {b:>10.4}  q {q0:.1} (deg/h)^2/h{}; GM {:.1} deg/h, {:.0} s (static-tuned)",
            "product (dual, drls-checked)",
            q_end(q0),
            gm.sigma_gm_dps * 3600.0,
            gm.tau_s
        );
        let (_, _, valid_calls) = product(&set.valid, s_valid, q, g, truth)?;
        let (a, b, test_calls) = product(&set.test, s_test, q, g, truth)?;
        println!(
            "{:<34} {name:<9} {a:>10.4} {b:>10.4}  q {q:.1} (deg/h)^2/h{}; GM {:.3} deg/h, {:.0} s (vehicle-tuned; validation {valid_rms:.4})",
            "product, q and GM vehicle-tuned",
            q_end(q),
            g.sigma_gm_dps * 3600.0,
            g.tau_s
        );
        flag_sets.push(if truth {
            Flags {
                name,
                valid: truth_valid.clone(),
                test: set.test.iter().map(|r| r.still_truth()).collect(),
                rwgm: Some(rwgm_truth),
            }
        } else {
            Flags {
                name,
                valid: valid_calls,
                test: test_calls,
                rwgm: None,
            }
        });
    }
    let rows: Vec<_> = set.train.iter().map(thermal_rows).collect();
    let thermal = fit_thermal(&rows, ThermalKalmanConfig::default().dtemp_tau_s);
    for f in &flag_sets {
        let print = |name: &str, (a, b): (f64, f64), picked: String| {
            println!("{name:<34} {:<9} {a:>10.4} {b:>10.4}  {picked}", f.name);
        };
        print(
            "alignment bias",
            score(&set.test, s_test, &f.test, &|_| {
                Ok(Box::new(AlignmentBias::default()))
            })?,
            String::new(),
        );
        let kalman = |q: f64| {
            move |s: &SensorConfig| -> Result<Box<dyn DriftEstimator>> {
                Ok(Box::new(GatedKalman::new(q, sample_var(s))))
            }
        };
        let (kq, _) = pick(&log_grid(1e-16, 1e-8, 2), |q| {
            Ok(score(&set.valid, s_valid, &f.valid, &kalman(*q))?.0)
        })?;
        print(
            "gated Kalman (tuned q)",
            score(&set.test, s_test, &f.test, &kalman(kq))?,
            format!("q {kq:.1e} (deg/s)^2/sample"),
        );
        if let Some(fit) = thermal {
            let tk = move |s: &SensorConfig| -> Result<Box<dyn DriftEstimator>> {
                let cfg = ThermalKalmanConfig {
                    q_dps2: kq,
                    r_dps2: sample_var(s),
                    ..ThermalKalmanConfig::default()
                };
                Ok(Box::new(ThermalKalman::with_fit(cfg, fit)))
            };
            print(
                "gated Kalman + thermal fit",
                score(&set.test, s_test, &f.test, &tk)?,
                "the Kalman's q".into(),
            );
        }
        let c = match f.rwgm {
            Some(c) => c,
            None => tune_rwgm(&f.valid)?,
        };
        print(
            "gated RW+GM Kalman (tuned)",
            score(&set.test, s_test, &f.test, &rwgm(c))?,
            rwgm_label(&c),
        );
        if bank {
            // The bank level alone in f64 (host_sim::nav::GatedBank, no model, no rollback):
            // what the product's level is worth with these flags; q and B tuned.
            let gated_bank = |q: f64, c: RwGmConfig| {
                move |s: &SensorConfig| -> Result<Box<dyn DriftEstimator>> {
                    Ok(Box::new(GatedBank::new(BankConfig {
                        q_rw_dps2_per_s: f64::from(q_dps2_per_s(q)),
                        b_dps: c.sigma_gm_dps,
                        tau_min_s: 1.0,
                        tau_max_s: c.tau_s,
                        per_decade: 1.0,
                        r_dps2: sample_var(s),
                        p0_dps2: c.p0_dps2,
                    })))
                }
            };
            let coarse: Vec<f64> = log_grid(0.25, 16384.0, 2);
            let mut g = gm;
            let mut q = 100.0;
            for _ in 0..2 {
                q = pick(&coarse, |q| {
                    Ok(score(&set.valid, s_valid, &f.valid, &gated_bank(*q, g))?.0)
                })?
                .0;
                g = pick(&bank_grid, |c| {
                    Ok(score(&set.valid, s_valid, &f.valid, &gated_bank(q, *c))?.0)
                })?
                .0;
            }
            print(
                "gated bank alone (f64, ablation)",
                score(&set.test, s_test, &f.test, &gated_bank(q, g))?,
                format!(
                    "q {q:.1} (deg/h)^2/h, B {:.3} deg/h, tau <= {:.0} s",
                    g.sigma_gm_dps * 3600.0,
                    g.tau_s
                ),
            );
        }
    }
    Ok(())
}
