//! The drift filter (fog-core `drift_filter`, the fitted gyro model's Kalman filter) on
//! gyro families, paired per vehicle with the product and the baselines `unit_family`
//! measured on the same records.
//!
//! Per family folder (as `scripts/gen_unit_family.py` lays it out):
//! 1. `train/`: the model fitted by `host_sim::gyro_fit` (printed), its two scales tuned on
//!    `vehicles-tune/` by `host_sim::motion::tune` (as `identify --tune-on`);
//! 2. `vehicles-test/`: heading RMS of the drift filter with its own stillness test and,
//!    as the detector's limit, with the truth's still flags; of no compensation;
//! 3. `static-test/`: e_truth = RMS(estimate - drift) / RMS(drift); beside it the
//!    random-walk baseline of `fog_lab::static_rw` with `q` picked on `train/` (the
//!    calibration runs, by their truth) and on the static records themselves (an oracle);
//! 4. when `DIR/today.json` exists (`unit_family --json DIR/today.json`): the same
//!    vehicles' rows of the product and its baselines, paired per vehicle: mean difference
//!    and its 95 % interval (Student t), per family and pooled over every family.
//!
//! ```sh
//! cargo run --release -p fog-lab --bin drift_filter_eval -- --family DIR [DIR...] [--json OUT]
//! ```

use anyhow::{Context, Result};
use clap::Parser;
use fog_core::drift_filter::{DriftFilter, DriftFilterConfig};
use fog_core::gyro_model::GyroModel;
use fog_lab::static_rw;
use host_sim::identify::series::{CsvFiles, Records, Series};
use host_sim::motion::calibration;
use host_sim::nav::{self, NavRecord};
use host_sim::record::{ReadOptions, Record};
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Evaluate the drift filter on gyro families (see the file's docs).
#[derive(Parser, Debug)]
struct Args {
    /// Family folders (train/, static-test/, vehicles-test/ [, today.json]).
    #[arg(long, num_args = 1..)]
    family: Vec<PathBuf>,
    /// Write every figure here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Window length, s.
    #[arg(long)]
    window_s: Option<f32>,
    /// Stillness threshold (chi-square(1) quantile).
    #[arg(long)]
    nis_limit: Option<f32>,
    /// Rate the test must resolve, deg/h.
    #[arg(long)]
    resolve_dph: Option<f32>,
    /// Exploration: set the model's rate random walk, deg/h/sqrt(h).
    #[arg(long)]
    rrw_dph_rth: Option<f32>,
    /// Exploration: multiply the Gauss-Markov sigmas.
    #[arg(long)]
    markov_scale: Option<f32>,
    /// Exploration: multiply the temperature links' spreads.
    #[arg(long)]
    prior_scale: Option<f32>,
    /// Write each vehicle's `t_s,drift_dps,estimate_dps,moving,temp_c,unit_estimate_dps`
    /// here (every 100th sample; the last column with `--unit-runs`).
    #[arg(long)]
    dump: Option<PathBuf>,
    /// Exploration: the warm-up time constant's range as this factor around the fit's.
    #[arg(long)]
    warmup_tau_ratio: Option<f32>,
    /// Exploration: multiply the warm-up's spread.
    #[arg(long)]
    warmup_scale: Option<f32>,
    /// Also the demo's family (host-sim's own simulator: `host_sim::demo`), its 12 training
    /// records, 32 tune and 32 test vehicles, scored in memory.
    #[arg(long)]
    demo_family: bool,
    /// Exploration: zero the links (mean and spread).
    #[arg(long)]
    no_links: bool,
    /// Print every vehicle.
    #[arg(long)]
    verbose: bool,
    /// Also the per-unit calibration scenario: each test vehicle's model fitted on its own
    /// unit's static runs (`unit-runs/vehicle-NN-r*.csv`, `gen_unit_family.py --unit-runs K`)
    /// instead of the family's `train/`, the rest as the family's (tuning included).
    #[arg(long)]
    unit_runs: bool,
}

#[derive(Debug, Serialize)]
struct Vehicle {
    record: String,
    raw_deg: f64,
    filter_deg: f64,
    filter_truth_flags_deg: f64,
    /// The filter of the vehicle's own model (its sidecar's truth) with the truth's flags.
    limit_deg: Option<f64>,
    /// The filter of the model fitted on the vehicle's own unit's static runs (`--unit-runs`).
    unit_runs_deg: Option<f64>,
    still_windows: u32,
    windows: u32,
    undone: u32,
    bound_reached_inside: bool,
    /// unit_family's rows for this record: [name, heading RMS deg].
    today: Vec<(String, f64)>,
}

/// The random-walk baseline at rest: every sample still, `r` each record's own, `q` picked
/// on the calibration runs and, as an oracle, on the static records themselves.
#[derive(Debug, Serialize)]
struct StaticRw {
    q_cal_dps2: f64,
    /// e_truth per static record with `q_cal_dps2`.
    e_truth_cal: Vec<f64>,
    q_oracle_dps2: f64,
    e_truth_oracle_mean: f64,
}

#[derive(Debug, Serialize)]
struct Family {
    family: String,
    model: String,
    fit: host_sim::gyro_fit::GyroFitReport,
    /// (link spread scale, Gauss-Markov scale, mean heading RMS on the tune vehicles).
    tuning: Vec<(f32, f32, f64, Option<f32>)>,
    vehicles: Vec<Vehicle>,
    static_e_truth: Vec<(String, f64)>,
    /// The limit's (each record's own model, every window still) e_truth per static record.
    static_limit: Vec<f64>,
    /// e_truth per static record with the model of its own unit's runs (`--unit-runs`).
    static_unit_runs: Vec<f64>,
    /// The random-walk baseline on the static records (`fog_lab::static_rw`).
    static_rw: StaticRw,
}

fn main() -> Result<()> {
    let args = Args::parse();
    let mut cfg = DriftFilterConfig::default();
    if let Some(w) = args.window_s {
        cfg.window_s = w;
    }
    if let Some(g) = args.nis_limit {
        cfg.nis_limit = g;
    }
    if let Some(r) = args.resolve_dph {
        cfg.resolve_dps = r / 3600.0;
    }
    let mut out = Vec::new();
    if args.demo_family {
        demo_family(cfg, &args)?;
    }
    for fam in &args.family {
        let f = family(fam, cfg, &args).with_context(|| format!("family {}", fam.display()))?;
        print_family(&f);
        if args.verbose {
            for v in &f.vehicles {
                println!(
                    "    {} raw {:.3} limit {:.3} unit-runs {:.3} filter {:.3} truth-flags {:.3} product {:.3} still {}/{} undone {}",
                    v.record,
                    v.raw_deg,
                    v.limit_deg.unwrap_or(f64::NAN),
                    v.unit_runs_deg.unwrap_or(f64::NAN),
                    v.filter_deg,
                    v.filter_truth_flags_deg,
                    v.today.first().map_or(f64::NAN, |t| t.1),
                    v.still_windows,
                    v.windows,
                    v.undone
                );
            }
        }
        out.push(f);
    }
    if out.len() > 1 {
        print_pooled(&out);
    }
    if let Some(p) = &args.json {
        std::fs::write(p, serde_json::to_string_pretty(&out)?)
            .with_context(|| format!("{}: cannot write", p.display()))?;
    }
    Ok(())
}

fn files(dir: &Path) -> Result<CsvFiles> {
    CsvFiles::from_args(&[dir.to_path_buf()], &ReadOptions::default())
}

fn name(p: &Path) -> String {
    p.file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Runs the filter over a record; `truth_flags`: the record's still truth as external flags.
/// The exploration options applied to a fitted model, in both the families' and the demo
/// family's runs: [`explore`], then `--rrw-dph-rth`, `--markov-scale`, `--no-links`,
/// `--warmup-scale`, `--warmup-tau-ratio` (each touches its own fields).
fn adjust(model: &mut GyroModel, args: &Args) {
    explore(model);
    if let Some(k) = args.rrw_dph_rth {
        model.rrw_dps_per_s_rthz = k / 3600.0 / 60.0;
    }
    if let Some(m) = args.markov_scale {
        for t in &mut model.markov {
            t.sigma_dps *= m;
        }
    }
    if args.no_links {
        model.temp_dps_per_c = Default::default();
        model.temp_rate_dps_per_c_per_s = Default::default();
    }
    if let Some(m) = args.warmup_scale {
        model.warmup_dps.sigma *= m;
    }
    if let Some(r) = args.warmup_tau_ratio {
        let mid = (model.warmup_tau_min_s * model.warmup_tau_max_s).sqrt();
        model.warmup_tau_min_s = mid / r;
        model.warmup_tau_max_s = mid * r;
    }
}

/// Exploration: `FOG_EXPLORE=key=scale,...` multiplies fitted model numbers the flags do
/// not reach (keys: linkmean, linksig, shupemean, shupesig, warmmean, turnsig, gm, rrw;
/// gmtau and gm2 set the Gauss-Markov terms' correlation times).
fn explore(m: &mut GyroModel) {
    let Ok(spec) = std::env::var("FOG_EXPLORE") else {
        return;
    };
    for kv in spec.split(',') {
        let Some((k, v)) = kv.split_once('=') else {
            continue;
        };
        let Ok(x) = v.parse::<f32>() else { continue };
        match k {
            "linkmean" => m.temp_dps_per_c.mean *= x,
            "linksig" => m.temp_dps_per_c.sigma *= x,
            "shupemean" => m.temp_rate_dps_per_c_per_s.mean *= x,
            "shupesig" => m.temp_rate_dps_per_c_per_s.sigma *= x,
            "warmmean" => m.warmup_dps.mean *= x,
            "turnsig" => m.turn_on_dps.sigma *= x,
            "gm" => m.markov.iter_mut().for_each(|t| t.sigma_dps *= x),
            "rrw" => m.rrw_dps_per_s_rthz *= x,
            "gmtau" => m.markov[0].tau_s = x,
            "gm2" => {
                m.markov[1] = fog_core::gyro_model::MarkovTerm {
                    sigma_dps: m.markov[0].sigma_dps * x,
                    tau_s: 300.0,
                };
                m.markov[2] = fog_core::gyro_model::MarkovTerm {
                    sigma_dps: m.markov[0].sigma_dps * x,
                    tau_s: 3000.0,
                };
            }
            _ => eprintln!("FOG_EXPLORE: unknown key {k}"),
        }
    }
    eprintln!("explored model: {m:?}");
}

fn run(
    model: GyroModel,
    cfg: DriftFilterConfig,
    r: &NavRecord,
    truth_flags: bool,
) -> Result<(Vec<f64>, fog_core::drift_filter::DriftStats)> {
    let mut f = DriftFilter::new(model, cfg).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut drift = Vec::with_capacity(r.len());
    let mut last = 0.0;
    for k in 0..r.len() {
        let temp = r
            .temp_c
            .as_ref()
            .and_then(|t| t.get(k).copied())
            .unwrap_or(f64::NAN) as f32;
        let flag = truth_flags.then(|| !r.moving[k]);
        if let Ok(o) = f.push(r.rate_dps[k] as f32, temp, flag) {
            last = f64::from(o.drift_dps);
        }
        drift.push(last);
    }
    Ok((drift, *f.stats()))
}

fn family(fam: &Path, cfg: DriftFilterConfig, args: &Args) -> Result<Family> {
    let train = files(&fam.join("train"))?;
    let mut runs: Vec<Series> = Vec::new();
    for i in 0..train.len() {
        runs.push(train.get(i)?);
    }
    let cal = calibration::measure(&runs)?;
    let (mut model, fit) = host_sim::gyro_fit::fit(&runs, &cal, 30.0 / 3600.0)?;
    adjust(&mut model, args);
    if let Some(m) = args.prior_scale {
        model.temp_dps_per_c.sigma *= m;
        model.temp_rate_dps_per_c_per_s.sigma *= m;
    }
    // Exploration: FOG_FAMILY_LINKS=1 puts the generator's family links (strong: shared
    // value, 20 % unit spread) in place of the fit's.
    if std::env::var("FOG_FAMILY_LINKS").is_ok() {
        if let Some(fam_json) = std::fs::read_to_string(fam.join("family.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        {
            let dph = 1.0 / 3600.0;
            let k1 = fam_json
                .pointer("/family/k1_dph_per_c")
                .and_then(Value::as_f64);
            let sh = fam_json
                .pointer("/family/shupe_dph_per_c_per_min")
                .and_then(Value::as_f64);
            eprintln!("family links {k1:?} {sh:?}");
            if let (Some(k1), Some(sh)) = (k1, sh) {
                model.temp_dps_per_c.mean = (k1 * dph) as f32;
                model.temp_dps_per_c.sigma = (0.2 * k1.abs() * dph) as f32;
                model.temp_rate_dps_per_c_per_s.mean = (sh * dph * 60.0) as f32;
                model.temp_rate_dps_per_c_per_s.sigma = (0.2 * sh.abs() * dph * 60.0) as f32;
            }
        }
    }
    // Tuning on the family's tune vehicles (as the product's identify --tune-on and the
    // baselines): the links' prior spread and the Gauss-Markov sigmas scaled, by the least
    // mean heading RMS with the filter's own test. Skipped when a scale is given.
    let mut tuning = Vec::new();
    let untuned = model;
    if args.prior_scale.is_none() && args.markov_scale.is_none() {
        let tune: Vec<NavRecord> = files(&fam.join("vehicles-tune"))?
            .0
            .iter()
            .map(|p| NavRecord::try_from(&Record::read(p, &ReadOptions::default())?))
            .collect::<Result<_>>()?;
        let image = fog_core::image::Image {
            model,
            config: cfg,
            full_scale_dps: 60.0,
            trained_runs: runs.len() as u32,
        };
        let (tuned, t) = host_sim::motion::tune::tune(&image, &tune)?;
        tuning = t
            .grid
            .iter()
            .map(|c| {
                (
                    c.link_scale,
                    c.markov_scale,
                    c.heading_rms_deg,
                    c.markov_tau_s,
                )
            })
            .collect();
        model = tuned.model;
    }
    let today: Option<Value> = std::fs::read_to_string(fam.join("today.json"))
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok());
    let today_rows = |rec: &str| -> Vec<(String, f64)> {
        let Some(recs) = today
            .as_ref()
            .and_then(|t| t.get(0))
            .and_then(|f| f.pointer("/vehicles_test/records"))
            .and_then(|r| r.as_array())
        else {
            return Vec::new();
        };
        recs.iter()
            .find(|r| r.get("record").and_then(|n| n.as_str()) == Some(rec))
            .and_then(|r| r.get("rows"))
            .and_then(|r| r.as_array())
            .map(|rows| {
                rows.iter()
                    .filter_map(|row| {
                        Some((row.get(0)?.as_str()?.to_string(), row.get(1)?.as_f64()?))
                    })
                    .collect()
            })
            .unwrap_or_default()
    };
    let mut vehicles = Vec::new();
    for p in files(&fam.join("vehicles-test"))?.0 {
        let r = NavRecord::try_from(&Record::read(&p, &ReadOptions::default())?)?;
        let (d, st) = run(model, cfg, &r, false)?;
        let (dt, _) = run(model, cfg, &r, true)?;
        let bound = f64::from(model.drift_bound_dps);
        let inside = r.drift_dps.iter().all(|v| v.abs() < bound);
        let reached = d.iter().any(|v| v.abs() >= bound * (1.0 - 1e-6));
        let rec = name(&p);
        let limit_deg = match true_model(&p, &model) {
            Some(m) => Some(nav::score_drift(&r, &run(m, cfg, &r, true)?.0).heading_rms_deg),
            None => None,
        };
        let unit_estimate = if args.unit_runs {
            let um = unit_model(fam, &p, &unit_family(&model, &untuned))?;
            Some(run(um, cfg, &r, false)?.0)
        } else {
            None
        };
        let unit_runs_deg = unit_estimate
            .as_ref()
            .map(|u| nav::score_drift(&r, u).heading_rms_deg);
        if let Some(dir) = &args.dump {
            let mut text =
                String::from("t_s,drift_dps,estimate_dps,moving,temp_c,unit_estimate_dps\n");
            for k in (0..r.len()).step_by(100) {
                let temp = r.temp_c.as_ref().map_or(f64::NAN, |t| t[k]);
                let unit = unit_estimate.as_ref().map_or(f64::NAN, |u| u[k]);
                text += &format!(
                    "{},{},{},{},{},{}\n",
                    r.t_s[k],
                    r.drift_dps[k],
                    d[k],
                    u8::from(r.moving[k]),
                    temp,
                    unit
                );
            }
            std::fs::write(dir.join(format!("{rec}.dump.csv")), text)?;
        }
        vehicles.push(Vehicle {
            raw_deg: nav::score_drift(&r, &[]).heading_rms_deg,
            filter_deg: nav::score_drift(&r, &d).heading_rms_deg,
            filter_truth_flags_deg: nav::score_drift(&r, &dt).heading_rms_deg,
            limit_deg,
            unit_runs_deg,
            still_windows: st.still_windows,
            windows: st.windows,
            undone: st.undone,
            bound_reached_inside: inside && reached,
            today: today_rows(&rec),
            record: rec,
        });
    }
    let mut static_e_truth = Vec::new();
    let mut static_limit = Vec::new();
    let mut static_unit_runs = Vec::new();
    // The random-walk baseline's q, picked on the calibration runs (module docs, 3).
    let mut cal_runs = Vec::new();
    for p in files(&fam.join("train"))?.0 {
        cal_runs.push(NavRecord::try_from(&Record::read(
            &p,
            &ReadOptions::default(),
        )?)?);
    }
    let rw_q_cal = static_rw::pick_q(&cal_runs.iter().collect::<Vec<_>>())
        .with_context(|| format!("{}: no calibration run scores", fam.display()))?
        .q_dps2;
    let mut static_recs = Vec::new();
    for p in files(&fam.join("static-test"))?.0 {
        let r = NavRecord::try_from(&Record::read(&p, &ReadOptions::default())?)?;
        let (d, st) = run(model, cfg, &r, false)?;
        if let Some(dir) = &args.dump {
            let mut text = String::from("t_s,drift_dps,estimate_dps,moving,temp_c\n");
            for k in (0..r.len()).step_by(100) {
                let temp = r.temp_c.as_ref().map_or(f64::NAN, |t| t[k]);
                text += &format!("{},{},{},0,{}\n", r.t_s[k], r.drift_dps[k], d[k], temp);
            }
            std::fs::write(dir.join(format!("{}.dump.csv", name(&p))), text)?;
        }
        let e = |d: &[f64]| static_rw::e_truth(d, &r.drift_dps);
        if args.verbose {
            let (dt, _) = run(model, cfg, &r, true)?;
            println!(
                "    static {}: e_truth {:.4}, every window still {:.4}; still {}/{} undone {}",
                name(&p),
                e(&d),
                e(&dt),
                st.still_windows,
                st.windows,
                st.undone
            );
        }
        static_e_truth.push((name(&p), e(&d)));
        if let Some(tm) = true_model(&p, &model) {
            static_limit.push(e(&run(tm, cfg, &r, true)?.0));
        }
        if args.unit_runs {
            let um = unit_model(fam, &p, &unit_family(&model, &untuned))?;
            static_unit_runs.push(e(&run(um, cfg, &r, false)?.0));
        }
        static_recs.push(r);
    }
    let static_rw_cal: Vec<f64> = static_recs
        .iter()
        .map(|r| {
            let est = static_rw::estimate(r, rw_q_cal, static_rw::diff_var_dps2(&r.rate_dps));
            static_rw::e_truth(&est, &r.drift_dps)
        })
        .collect();
    let rw_oracle = static_rw::pick_q(&static_recs.iter().collect::<Vec<_>>())
        .with_context(|| format!("{}: no static record scores", fam.display()))?;
    Ok(Family {
        family: fam.display().to_string(),
        model: format!("{model:?}"),
        fit,
        tuning,
        vehicles,
        static_e_truth,
        static_limit,
        static_unit_runs,
        static_rw: StaticRw {
            q_cal_dps2: rw_q_cal,
            e_truth_cal: static_rw_cal,
            q_oracle_dps2: rw_oracle.q_dps2,
            e_truth_oracle_mean: rw_oracle.mean_e_truth,
        },
    })
}

/// The family model a unit is made from (as `identify --tune-on --unit-runs`,
/// [`host_sim::motion::personalize`]): the tuned one with the Gauss-Markov terms as fitted.
/// Exploration: FOG_UNIT_TUNED_GM=1 keeps the tuned ones (before that choice).
fn unit_family(tuned: &GyroModel, untuned: &GyroModel) -> GyroModel {
    let mut m = *tuned;
    if std::env::var("FOG_UNIT_TUNED_GM").is_err() {
        m.markov = untuned.markov;
    }
    m
}

/// How many of a unit's own runs to use (`FOG_UNIT_RUNS_N`), when set.
fn unit_runs_n() -> Option<usize> {
    std::env::var("FOG_UNIT_RUNS_N")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
}

/// The model fitted on the vehicle's own unit's static runs (`unit-runs/STEM-r*.csv`; the
/// first FOG_UNIT_RUNS_N of them when set), made the unit's by
/// [`host_sim::gyro_fit::personalize`] with the (tuned) family model.
fn unit_model(fam: &Path, vehicle: &Path, family: &GyroModel) -> Result<GyroModel> {
    let stem = name(vehicle).trim_end_matches(".csv").to_string();
    let dir = fam.join("unit-runs");
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("{}: cannot list", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|q| {
            let n = name(q);
            n.starts_with(&format!("{stem}-r")) && n.ends_with(".csv")
        })
        .collect();
    paths.sort();
    if let Some(n) = unit_runs_n() {
        paths.truncate(n);
    }
    anyhow::ensure!(
        paths.len() >= 2,
        "{}: fewer than 2 runs of {stem}",
        dir.display()
    );
    let csv = CsvFiles::from_args(&paths, &ReadOptions::default())?;
    let mut runs = Vec::new();
    for i in 0..paths.len() {
        runs.push(csv.get(i)?);
    }
    let cal = calibration::measure(&runs)?;
    // FOG_UNIT_NOISE=own: the unit's runs' fit alone (no family part).
    // The family model comes with the exploration flags applied (adjust: not again).
    let m = if std::env::var("FOG_UNIT_NOISE").as_deref() == Ok("own") {
        host_sim::gyro_fit::fit(&runs, &cal, 30.0 / 3600.0)?.0
    } else {
        host_sim::gyro_fit::fit_unit(&runs, &cal, 30.0 / 3600.0, family)?.0
    };
    if std::env::var("FOG_UNIT_VERBOSE").is_ok() {
        eprintln!("unit model {stem}: {m:?}");
    }
    Ok(m)
}

/// The vehicle's own model from the generator's sidecar (`RECORD.csv.json`), on `fitted`'s
/// sample rate, quantum and bound: white noise, rate random walk, turn-on (centre and
/// power-on spread), the larger warm-up exactly, the links exactly (their spread 0). The
/// flicker of bias instability `B` is three Gauss-Markov terms of sigma `B` at 30, 300 and
/// 3000 s (an approximation: a flat Allan floor near 0.7 B over 30..3000 s). Not modelled:
/// the second, short warm-up (10..120 s), the quadratic temperature term, and the filter's
/// temperature rate is its causal estimate, not the truth's. So this is close to, not at,
/// the causal limit.
fn true_model(csv: &Path, fitted: &GyroModel) -> Option<GyroModel> {
    let text = std::fs::read_to_string(format!("{}.json", csv.display())).ok()?;
    let v: Value = serde_json::from_str(&text).ok()?;
    let s = v.get("sensor")?;
    let f = |k: &str| s.get(k).and_then(Value::as_f64);
    let dph = 1.0 / 3600.0;
    let b = f("bias_instability_dph")? * dph;
    let mut m = *fitted;
    m.white_dps_rthz = (f("arw_deg_rth")? / 60.0) as f32;
    for (t, tau) in m.markov.iter_mut().zip([30.0, 300.0, 3000.0]) {
        t.sigma_dps = b as f32;
        t.tau_s = tau;
    }
    m.rrw_dps_per_s_rthz = (f("rrw_dph_rth")? * dph / 60.0) as f32;
    m.temp_ref_c = v.pointer("/family/t_ref_c").and_then(Value::as_f64)? as f32;
    m.turn_on_dps.mean = (f("turn_on_centre_dph")? * dph) as f32;
    m.turn_on_dps.sigma = (f("turn_on_sigma_dph")? * dph) as f32;
    m.warmup_dps.mean = (f("warmup1_dph")? * dph) as f32;
    m.warmup_dps.sigma = 0.0;
    m.warmup_tau_min_s = f("warmup1_tau_s")? as f32;
    m.warmup_tau_max_s = m.warmup_tau_min_s;
    m.temp_dps_per_c.mean = (f("k1_dph_per_c")? * dph) as f32;
    m.temp_dps_per_c.sigma = 0.0;
    m.temp_rate_dps_per_c_per_s.mean = (f("shupe_dph_per_c_per_min")? * dph * 60.0) as f32;
    m.temp_rate_dps_per_c_per_s.sigma = 0.0;
    // Exploration: FOG_LIMIT_ABLATE=warmup|links|noise puts the fitted family's part back.
    match std::env::var("FOG_LIMIT_ABLATE").as_deref() {
        Ok("warmup") => {
            m.warmup_dps = fitted.warmup_dps;
            m.warmup_tau_min_s = fitted.warmup_tau_min_s;
            m.warmup_tau_max_s = fitted.warmup_tau_max_s;
        }
        Ok("warmup-tau") => {
            m.warmup_tau_min_s = fitted.warmup_tau_min_s;
            m.warmup_tau_max_s = fitted.warmup_tau_max_s;
        }
        Ok("links") => {
            m.temp_dps_per_c = fitted.temp_dps_per_c;
            m.temp_rate_dps_per_c_per_s = fitted.temp_rate_dps_per_c_per_s;
        }
        Ok("family") => {
            // The family's true distribution (a perfect calibration of the family), the
            // unit's own noise: what no knowledge of the unit's own constants adds.
            let fam = v.get("family")?;
            let ff = |k: &str| fam.get(k).and_then(Value::as_f64);
            let scale = f("turn_on_sigma_dph")? / 5.0;
            let sd_u = |half: f64| half / 3f64.sqrt();
            m.turn_on_dps.mean = 0.0;
            m.turn_on_dps.sigma =
                ((sd_u(50.0 * scale).powi(2) + (5.0 * scale).powi(2)).sqrt() * dph) as f32;
            m.warmup_dps.mean = 0.0;
            m.warmup_dps.sigma = ((sd_u(40.0).powi(2) + sd_u(5.0).powi(2)).sqrt() * dph) as f32;
            m.warmup_tau_min_s = 100.0;
            m.warmup_tau_max_s = 1500.0;
            match (
                ff("k1_dph_per_c"),
                ff("shupe_dph_per_c_per_min"),
                ff("link_unit_spread"),
            ) {
                (Some(k1), Some(sh), Some(sp)) => {
                    m.temp_dps_per_c.mean = (k1 * dph) as f32;
                    m.temp_dps_per_c.sigma = (sp * k1.abs() * dph) as f32;
                    m.temp_rate_dps_per_c_per_s.mean = (sh * dph * 60.0) as f32;
                    m.temp_rate_dps_per_c_per_s.sigma = (sp * sh.abs() * dph * 60.0) as f32;
                }
                _ => {
                    m.temp_dps_per_c.mean = 0.0;
                    m.temp_dps_per_c.sigma = (sd_u(0.05) * dph) as f32;
                    m.temp_rate_dps_per_c_per_s.mean = 0.0;
                    m.temp_rate_dps_per_c_per_s.sigma = (sd_u(0.5) * dph * 60.0) as f32;
                }
            }
        }
        Ok("noise") => {
            m.markov = fitted.markov;
            m.rrw_dps_per_s_rthz = fitted.rrw_dps_per_s_rthz;
            m.turn_on_dps = fitted.turn_on_dps;
        }
        _ => {}
    }
    m.is_valid().then_some(m)
}

/// Student t quantile 0.975 for `df` degrees of freedom (Cornish-Fisher, within 1e-3 for
/// df >= 5).
fn t975(df: f64) -> f64 {
    let z: f64 = 1.959_964;
    z + (z.powi(3) + z) / (4.0 * df)
        + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * df * df)
}

/// Mean and 95 % half-width of `d`.
fn paired(d: &[f64]) -> (f64, f64) {
    let n = d.len() as f64;
    let m = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, t975(n - 1.0) * (var / n).sqrt())
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    s / n as f64
}

/// Columns compared: (label, value per vehicle).
fn columns(v: &Vehicle) -> Vec<(String, f64)> {
    let mut c = vec![
        ("filter".to_string(), v.filter_deg),
        ("filter, truth flags".to_string(), v.filter_truth_flags_deg),
        ("raw".to_string(), v.raw_deg),
    ];
    if let Some(l) = v.limit_deg {
        c.push(("limit: true model".to_string(), l));
    }
    if let Some(u) = v.unit_runs_deg {
        c.push(("filter, own unit's runs".to_string(), u));
    }
    for (n, x) in &v.today {
        if n != "none" && n != "no compensation" {
            c.push((n.clone(), *x));
        }
    }
    c
}

/// The records on which `deg` (a column of the vehicle, when it has one) is worse than
/// the raw gyro's heading RMS plus 0.3 deg.
fn worse_than_raw<'a>(vs: &[&'a Vehicle], deg: impl Fn(&Vehicle) -> Option<f64>) -> Vec<&'a str> {
    vs.iter()
        .filter(|v| deg(v).is_some_and(|d| d > v.raw_deg + 0.3))
        .map(|v| v.record.as_str())
        .collect()
}

fn report(vs: &[&Vehicle]) {
    let cols = columns(vs[0]);
    println!(
        "  mean heading RMS over {} vehicles, and filter minus each (paired, 95 % interval):",
        vs.len()
    );
    for (i, (label, _)) in cols.iter().enumerate() {
        let vals: Vec<f64> = vs
            .iter()
            .map(|v| columns(v).get(i).map_or(f64::NAN, |c| c.1))
            .collect();
        let diffs: Vec<f64> = vs
            .iter()
            .zip(&vals)
            .map(|(v, x)| v.filter_deg - x)
            .collect();
        let (m, h) = paired(&diffs);
        let wins = diffs.iter().filter(|d| **d < 0.0).count();
        println!(
            "    {label:<22} {:8.3} deg   filter - it: {m:+8.3} +- {h:.3}   filter below on {wins}/{}",
            mean(vals.iter().copied()),
            vs.len()
        );
    }
    let worse = worse_than_raw(vs, |v| Some(v.filter_deg));
    let bound: Vec<&str> = vs
        .iter()
        .filter(|v| v.bound_reached_inside)
        .map(|v| v.record.as_str())
        .collect();
    println!(
        "  filter worse than raw + 0.3 deg: {} {:?}",
        worse.len(),
        worse
    );
    let limit_worse = worse_than_raw(vs, |v| v.limit_deg);
    println!(
        "  limit (true model) worse than raw + 0.3 deg: {} {:?}",
        limit_worse.len(),
        limit_worse
    );
    if vs.iter().any(|v| v.unit_runs_deg.is_some()) {
        let unit_worse = worse_than_raw(vs, |v| v.unit_runs_deg);
        println!(
            "  filter on its own unit's runs worse than raw + 0.3 deg: {} {:?}",
            unit_worse.len(),
            unit_worse
        );
    }
    println!(
        "  drift bound reached where the true drift stays inside: {} {:?}",
        bound.len(),
        bound
    );
}

fn print_family(f: &Family) {
    println!("== {}", f.family);
    println!("  model: {}", f.model);
    println!(
        "  warm-up tau {:.0} s (terms {:?}); ADEV after the deterministic part (tau s, deg/h; fit): {}",
        f.fit.warmup_tau_s,
        [f.fit.warmup_tau_s / 3.0, f.fit.warmup_tau_s * 3.0],
        f.fit
            .adev_dph
            .iter()
            .zip(&f.fit.fit_adev_dph)
            .map(|((t, a), (_, b))| format!("{t:.0}:{a:.2}/{b:.2}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    if let Some(best) = f.tuning.iter().min_by(|a, b| a.2.total_cmp(&b.2)) {
        println!(
            "  tuned on the tune vehicles: link spread x{}, Gauss-Markov x{}{} ({:.3} deg there)",
            best.0,
            best.1,
            best.3
                .map_or(String::new(), |t| format!(" in one term of {t} s")),
            best.2
        );
    }
    let vs: Vec<&Vehicle> = f.vehicles.iter().collect();
    report(&vs);
    let windows: u32 = f.vehicles.iter().map(|v| v.windows).sum();
    let still: u32 = f.vehicles.iter().map(|v| v.still_windows).sum();
    let undone: u32 = f.vehicles.iter().map(|v| v.undone).sum();
    println!("  windows still {still} of {windows}, updates undone {undone}");
    println!(
        "  static e_truth mean {:.4} ({} records); limit (own model, every window still) {:.4}",
        mean(f.static_e_truth.iter().map(|x| x.1)),
        f.static_e_truth.len(),
        mean(f.static_limit.iter().copied())
    );
    if !f.static_unit_runs.is_empty() {
        println!(
            "  static e_truth with the model of the unit's own runs {:.4}",
            mean(f.static_unit_runs.iter().copied())
        );
    }
    let rw = &f.static_rw;
    println!(
        "  static e_truth of a random-walk Kalman filter (every sample still, r each record's own): q from the calibration runs ({:.2e} (deg/s)^2/sample) {:.4}; q tuned on these records ({:.2e}) {:.4}",
        rw.q_cal_dps2,
        mean(rw.e_truth_cal.iter().copied()),
        rw.q_oracle_dps2,
        rw.e_truth_oracle_mean
    );
}

fn print_pooled(fs: &[Family]) {
    let vs: Vec<&Vehicle> = fs.iter().flat_map(|f| f.vehicles.iter()).collect();
    println!("== pooled over {} families", fs.len());
    if vs.iter().all(|v| v.today.len() == vs[0].today.len()) {
        report(&vs);
    }
}

/// The demo's family: the same fit and tuning as the product's `demo`, each test vehicle
/// scored with the filter's own test and with the truth's flags, beside the gated Kalman
/// filter with the truth's flags (its q tuned on the tune vehicles).
fn demo_family(cfg: DriftFilterConfig, args: &Args) -> Result<()> {
    use host_sim::demo::{family_model, samples, TrainingSet, VEHICLE_SEED, VEHICLE_UNIT};
    let set = TrainingSet {
        n: 12,
        duration_s: 1800.0,
    };
    let mut runs = Vec::new();
    for i in 0..set.len() {
        runs.push(set.get(i)?);
    }
    let cal = calibration::measure(&runs)?;
    let (mut model, fit) = host_sim::gyro_fit::fit(&runs, &cal, 30.0 / 3600.0)?;
    adjust(&mut model, args);
    let untuned = model;
    println!("== demo family: model {model:?}");
    println!(
        "  warm-up tau {:.0} s (terms {:?}); ADEV {:?}",
        fit.warmup_tau_s,
        [fit.warmup_tau_s / 3.0, fit.warmup_tau_s * 3.0],
        fit.adev_dph
    );
    let vehicles = |unit0: u64, seed0: u64| -> Result<Vec<NavRecord>> {
        (0..32)
            .map(|i| {
                Ok(NavRecord::from_samples(&samples(
                    &family_model(unit0 + i, true)?,
                    seed0 + i,
                    1800.0,
                )?))
            })
            .collect()
    };
    let tune = vehicles(800, 201)?;
    let test = vehicles(VEHICLE_UNIT, VEHICLE_SEED)?;
    let image = fog_core::image::Image {
        model,
        config: cfg,
        full_scale_dps: 60.0,
        trained_runs: 12,
    };
    let image = if args.markov_scale.is_some() {
        image
    } else {
        let (tuned, t) = host_sim::motion::tune::tune(&image, &tune)?;
        println!("  {}", host_sim::motion::tune::describe(&t));
        tuned
    };
    let r_dps2 = f64::from(image.model.sample_var_dps2());
    let q = nav::tune_gated_q(&tune, r_dps2, &nav::log_grid(1e-16, 1e-8, 4))
        .ok_or_else(|| anyhow::anyhow!("no tune vehicle"))?;
    let (mut own, mut truth, mut zaru, mut raw) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut unit_runs_deg = Vec::new();
    let family = unit_family(&image.model, &untuned);
    for (i, r) in test.iter().enumerate() {
        if args.unit_runs {
            // The test unit's own static runs: power-ons of the same unit (its constants
            // from its unit seed), each with its own noise, turn-on and conditions.
            let unit = VEHICLE_UNIT + i as u64;
            let n_runs = unit_runs_n().unwrap_or(4) as u64;
            let mut unit_runs = Vec::new();
            for k in 0..n_runs {
                let seed = DEMO_UNIT_RUN_SEED + 100 * i as u64 + k;
                unit_runs.push(host_sim::demo::static_run(unit, seed, 1800.0)?);
            }
            let ucal = calibration::measure(&unit_runs)?;
            let um = host_sim::gyro_fit::fit_unit(&unit_runs, &ucal, 30.0 / 3600.0, &family)?.0;
            unit_runs_deg.push(nav::score_drift(r, &run(um, cfg, r, false)?.0).heading_rms_deg);
        }
        own.push(nav::score_drift(r, &run(image.model, cfg, r, false)?.0).heading_rms_deg);
        truth.push(nav::score_drift(r, &run(image.model, cfg, r, true)?.0).heading_rms_deg);
        let mut g = nav::GatedKalman::new(q.q_dps2, r_dps2);
        zaru.push(nav::run(r, &mut g, &r.still_truth()).scores.heading_rms_deg);
        raw.push(nav::score_drift(r, &[]).heading_rms_deg);
    }
    let m = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let d: Vec<f64> = own.iter().zip(&zaru).map(|(a, b)| a - b).collect();
    let (md, h) = paired(&d);
    println!(
        "  32 test vehicles: filter {:.4} deg, filter with truth flags {:.4}, gated Kalman with truth flags (q {:.1e}) {:.4}, raw {:.4}; filter - gated {md:+.4} +- {h:.4}",
        m(&own),
        m(&truth),
        q.q_dps2,
        m(&zaru),
        m(&raw)
    );
    if !unit_runs_deg.is_empty() {
        let du: Vec<f64> = unit_runs_deg
            .iter()
            .zip(&zaru)
            .map(|(a, b)| a - b)
            .collect();
        let (mu, hu) = paired(&du);
        let df: Vec<f64> = unit_runs_deg.iter().zip(&own).map(|(a, b)| a - b).collect();
        let (mf, hf) = paired(&df);
        let below = du.iter().filter(|&&v| v < 0.0).count();
        let worse = unit_runs_deg
            .iter()
            .zip(&raw)
            .filter(|(a, b)| **a > **b + 0.3)
            .count();
        println!(
            "  the unit's own runs: filter {:.4} deg; minus gated with truth flags {mu:+.4} +- {hu:.4} (below it on {below} of {}); minus the family image {mf:+.4} +- {hf:.4}; worse than raw + 0.3 deg on {worse}",
            m(&unit_runs_deg),
            du.len()
        );
    }
    Ok(())
}

/// First seed of the demo test units' own static runs (`--demo-family --unit-runs`): apart
/// from the training (101..), tune (201..) and test vehicles' seeds.
const DEMO_UNIT_RUN_SEED: u64 = 70_000;
