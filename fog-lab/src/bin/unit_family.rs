//! Evaluation of the product on gyro families, apart from it: it runs the BUILT `host-sim`
//! binary as a subprocess (so it measures whatever the product is: today the drift filter,
//! `fog_core::drift_filter`, of the image `identify --preset motion` fits) and scores its
//! output against the records' truth beside causal baselines. The tables call the product's
//! row "identifier".
//!
//! A family is a folder (as `scripts/gen_unit_family.py` lays it out):
//! `train/*.csv` (static calibration runs), `static-test/*.csv` (other units, static),
//! `vehicles-tune/*.csv` and `vehicles-test/*.csv` (other units, vehicle records: an
//! alignment still at the start, then stops and drives), every CSV
//! `t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving`.
//!
//! Per family:
//! 1. `host-sim identify --preset motion --input train --save-identifier img.fogi
//!    --tune-on vehicles-tune --json identify.json [extra args after --]`, timed.
//! 2. static-test: `host-sim replay` of each record with the image; e_truth =
//!    RMS(drift estimate - drift_dps) / RMS(drift_dps) computed here from the replay's
//!    `drift_dps` column (no compensation: 1), and the fraction of samples its stillness
//!    test flagged still. Beside it the plain random-walk Kalman filter with EVERY sample
//!    still ([`host_sim::nav::GatedKalman`], all flags true, `fog_lab::static_rw`) whose
//!    `r` is the record's `var(first differences) / 2` (a user does not know the unit's white noise; the differences of a
//!    static record give it, from the whole record, so this `r` is not causal) and whose `q`
//!    is tuned ON THE VERY static-test records (log grid, least mean e_truth): the issue's
//!    goal is "the image's e_truth <= 0.10 and below the best random-walk Kalman filter
//!    tuned on the very records". Also the self-calibrated gated Kalman
//!    ([`SelfCalKalman`], q from the tune vehicles) with its own detector.
//! 3. vehicles-test: `host-sim replay ... --validate vehicles-tune` (the baselines' q tuned
//!    there with the truth's still flags) gives the heading-error RMS of the identifier and
//!    of every baseline row; beside them [`SelfCalKalman`] with its q tuned on the tune
//!    vehicles with its own detector ([`nav::tune_selfcal_q`], least mean heading RMS, the
//!    protocol of `identify --tune-on`; grid 1e-18..1e-6). Counted: the test vehicles on
//!    which the identifier is below every causal baseline (no compensation aside).
//! 4. A table per family on stdout, every figure in `--json`.
//!
//! ```sh
//! cargo build --release -p host-sim
//! cargo run --release -p fog-lab --bin unit_family -- --family DIR [--family DIR2 ...] \
//!     [--host-sim PATH] [--json OUT.json] [--work DIR] [-- extra identify args, e.g. --gyro FILE]
//! ```

use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use fog_lab::static_rw::{self, diff_var_dps2, e_truth, STATIC_Q_GRID};
use host_sim::identify::series::CsvFiles;
use host_sim::nav::{self, NavRecord, SelfCalConfig, SelfCalKalman};
use host_sim::record::{ReadOptions, Record};
use serde::Serialize;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Evaluate the product's estimator on gyro families (see the file's docs).
#[derive(Parser, Debug)]
struct Args {
    /// Family folders (train/, static-test/, vehicles-tune/, vehicles-test/).
    #[arg(long, required = true, num_args = 1..)]
    family: Vec<PathBuf>,
    /// The host-sim binary (default: the workspace's target/release/host-sim).
    #[arg(long)]
    host_sim: Option<PathBuf>,
    /// Write every figure here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Keep the images, replay outputs and logs here (default: a temporary folder, removed).
    #[arg(long)]
    work: Option<PathBuf>,
    /// Extra arguments for `identify` (after `--`).
    #[arg(last = true)]
    identify_args: Vec<String>,
}

/// q grid of the self-calibrated gated Kalman filter on the tune vehicles: replay's grid
/// for the gated Kalman (1e-18..1e-8, 2 per decade) widened to 1e-6 (a family with a strong
/// temperature link picked 1e-8, that grid's end).
const SELFCAL_Q_GRID: (f64, f64, usize) = (1e-18, 1e-6, 2);
/// The issue's goal for the image's e_truth on static units.
const E_TRUTH_GOAL: f64 = 0.10;

#[derive(Debug, Serialize)]
struct QPick {
    q_dps2: f64,
    /// Mean score at the pick (e_truth ratio or heading RMS deg).
    score: f64,
    grid_lo: f64,
    grid_hi: f64,
    per_decade: usize,
    at_grid_end: bool,
    grid: Vec<(f64, f64)>,
}

impl QPick {
    fn new(t: &nav::Tuning, g: (f64, f64, usize)) -> Self {
        let at_grid_end = t
            .grid
            .first()
            .zip(t.grid.last())
            .is_some_and(|(a, b)| t.q_dps2 == a.0 || t.q_dps2 == b.0);
        Self {
            q_dps2: t.q_dps2,
            score: t.heading_rms_deg,
            grid_lo: g.0,
            grid_hi: g.1,
            per_decade: g.2,
            at_grid_end,
            grid: t.grid.clone(),
        }
    }

    fn text(&self) -> String {
        format!(
            "q {:.2e} (deg/s)^2/sample, grid {:.0e}..{:.0e} x{}/decade{}",
            self.q_dps2,
            self.grid_lo,
            self.grid_hi,
            self.per_decade,
            if self.at_grid_end {
                ", AT A GRID END"
            } else {
                ""
            }
        )
    }
}

#[derive(Debug, Serialize)]
struct StaticRecord {
    record: String,
    samples: usize,
    rms_drift_dph: f64,
    identifier_e_truth: f64,
    identifier_still_fraction: f64,
    /// The replay's own e_truth (deg/h) for the identifier row, a cross-check of the
    /// numerator computed here.
    replay_identifier_e_truth_dph: Option<f64>,
    rw_kalman_r_dps2: f64,
    /// sqrt(r / the image's sensor noise variance per sample, from the replay JSON's
    /// `sensor`): the unit's white noise against the reference the identifier's detector
    /// uses (the specification's, or one the image learned).
    noise_x_image: Option<f64>,
    rw_kalman_e_truth: f64,
    selfcal_e_truth: f64,
    selfcal_still_fraction: f64,
    selfcal_noise_var_dps2: Option<f64>,
}

#[derive(Debug, Serialize)]
struct StaticTest {
    records: Vec<StaticRecord>,
    mean_identifier_e_truth: f64,
    mean_identifier_still_fraction: f64,
    mean_rw_kalman_e_truth: f64,
    mean_selfcal_e_truth: f64,
    /// The all-still random-walk Kalman filter's q, tuned on these very records.
    rw_kalman_q: QPick,
    /// Mean identifier e_truth <= 0.10 and below the tuned random-walk Kalman's.
    goal_met: bool,
}

#[derive(Debug, Serialize)]
struct VehicleRecord {
    record: String,
    /// Rows: (name, heading-error RMS deg, e_truth = RMS(est - drift) / RMS(drift)); the
    /// replay's rows in order, then the self-calibrated filter with its tuned q.
    rows: Vec<(String, f64, Option<f64>)>,
    /// The truth's still fraction (`moving` = 0).
    truth_still_fraction: f64,
    identifier_still_fraction: f64,
    /// sqrt(the self-calibrated filter's alignment noise / the image's sensor noise), as
    /// [`StaticRecord::noise_x_image`].
    noise_x_image: Option<f64>,
    detector_false_still_rate: Option<f64>,
    detector_missed_still_rate: Option<f64>,
    selfcal_tuned_still_fraction: f64,
    identifier_below_every_baseline: bool,
}

#[derive(Debug, Serialize)]
struct VehiclesTest {
    records: Vec<VehicleRecord>,
    mean_heading_rms_deg: Vec<(String, f64)>,
    identifier_best: usize,
    /// The replay's baselines' q and where it came from.
    baseline_q_dps2: Option<f64>,
    baseline_q_source: Option<String>,
    /// The self-calibrated filter's q, tuned on the tune vehicles (its own detector).
    selfcal_q: QPick,
}

#[derive(Debug, Serialize)]
struct Family {
    family: String,
    host_sim: String,
    identify_args: Vec<String>,
    identify_wall_s: f64,
    train_records: usize,
    tune_vehicles: usize,
    /// `identify --json`'s `tuning` (the level's picks on the tune vehicles).
    identify_tuning: Value,
    /// The picked candidate's tuning, as text.
    identify_tuning_text: Option<String>,
    static_test: StaticTest,
    vehicles_test: VehiclesTest,
}

fn main() -> Result<()> {
    let a = Args::parse();
    let exe = a.host_sim.clone().unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/release/host-sim")
    });
    if !exe.is_file() {
        bail!(
            "{}: no host-sim binary (build it: cargo build --release -p host-sim, or give --host-sim)",
            exe.display()
        );
    }
    let tmp;
    let work = match &a.work {
        Some(w) => w.clone(),
        None => {
            tmp = tempfile::tempdir().context("temporary folder")?;
            tmp.path().to_path_buf()
        }
    };
    let mut out = Vec::new();
    for (i, fam) in a.family.iter().enumerate() {
        let dir = work.join(format!("family-{i:02}"));
        std::fs::create_dir_all(&dir).with_context(|| format!("{}", dir.display()))?;
        let f = family(fam, &exe, &a.identify_args, &dir)?;
        print_family(&f);
        out.push(f);
    }
    if let Some(j) = &a.json {
        let text = serde_json::to_string_pretty(&out)?;
        std::fs::write(j, text).with_context(|| format!("{}: cannot write", j.display()))?;
        println!("figures -> {}", j.display());
    }
    Ok(())
}

fn csvs(dir: &Path) -> Result<Vec<PathBuf>> {
    Ok(CsvFiles::from_args(&[dir.to_path_buf()], &ReadOptions::default())?.0)
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into())
}

/// Runs `exe args`, its stderr to `log`; fails with the log's tail.
fn run_host_sim(exe: &Path, args: &[&std::ffi::OsStr], log: &Path) -> Result<()> {
    let o = Command::new(exe)
        .args(args)
        .output()
        .with_context(|| format!("{}: cannot run", exe.display()))?;
    std::fs::write(log, &o.stderr).with_context(|| format!("{}", log.display()))?;
    if !o.status.success() {
        let err = String::from_utf8_lossy(&o.stderr);
        let tail: Vec<&str> = err.lines().rev().take(15).collect();
        bail!(
            "{} {:?} failed ({}):\n{}",
            exe.display(),
            args,
            o.status,
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        );
    }
    Ok(())
}

fn read_json(p: &Path) -> Result<Value> {
    let text = std::fs::read_to_string(p).with_context(|| format!("{}", p.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not JSON", p.display()))
}

/// The replay output's `drift_dps` (deg/s) and `still` (0/1) columns (host-sim's record
/// reader: the output has `t_s`).
fn read_replay_csv(p: &Path) -> Result<(Vec<f64>, Vec<bool>)> {
    let opts = ReadOptions {
        still_column: Some("still".into()),
        optional_columns: false,
        ..ReadOptions::rate("drift_dps", 1.0)
    };
    let r = Record::read(p, &opts)?;
    let still = r.still.unwrap_or_default();
    Ok((
        r.rate_dps,
        still.into_iter().map(|s| s == Some(true)).collect(),
    ))
}

/// A record with its truth, as host-sim scores it.
fn read_truth(p: &Path) -> Result<NavRecord> {
    NavRecord::try_from(&Record::read(p, &ReadOptions::default())?)
}

/// The noise variance per sample of the sensor in a replay's JSON (`sensor`), (deg/s)^2:
/// `density^2 * rate + quantum^2 / 12`, as fog_core's `SensorConfig::sample_var_dps2`.
fn spec_var_dps2(replay_json: &Value) -> Option<f64> {
    let s = &replay_json["sensor"];
    let nd = s["noise_density_dps_rthz"].as_f64()?;
    let hz = s["sample_rate_hz"].as_f64()?;
    let q = s["quantum_dps"].as_f64()?;
    Some(nd * nd * hz + q * q / 12.0)
}

fn rms(x: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for v in x {
        s += v * v;
        n += 1;
    }
    (s / n.max(1) as f64).sqrt()
}

fn fraction(flags: &[bool]) -> f64 {
    flags.iter().filter(|&&s| s).count() as f64 / flags.len().max(1) as f64
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x;
        n += 1;
    }
    s / n.max(1) as f64
}

/// Replays `rec` through `img`; returns the output CSV and JSON paths.
fn replay(
    exe: &Path,
    img: &Path,
    rec: &Path,
    dir: &Path,
    tag: &str,
    extra: &[&std::ffi::OsStr],
) -> Result<(PathBuf, PathBuf)> {
    let stem = format!("{tag}-{}", file_name(rec).trim_end_matches(".csv"));
    let (csv, json, log) = (
        dir.join(format!("{stem}.out.csv")),
        dir.join(format!("{stem}.json")),
        dir.join(format!("{stem}.log")),
    );
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "replay".as_ref(),
        "--input".as_ref(),
        rec.as_os_str(),
        "--identifier".as_ref(),
        img.as_os_str(),
        "--output".as_ref(),
        csv.as_os_str(),
        "--json".as_ref(),
        json.as_os_str(),
    ];
    args.extend_from_slice(extra);
    run_host_sim(exe, &args, &log)?;
    Ok((csv, json))
}

fn family(fam: &Path, exe: &Path, extra: &[String], dir: &Path) -> Result<Family> {
    let (train, stest, vtune, vtest) = (
        fam.join("train"),
        fam.join("static-test"),
        fam.join("vehicles-tune"),
        fam.join("vehicles-test"),
    );
    let img = dir.join("img.fogi");
    let id_json = dir.join("identify.json");
    // 1. identify.
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "identify".as_ref(),
        "--preset".as_ref(),
        "motion".as_ref(),
        "--input".as_ref(),
        train.as_os_str(),
        "--save-identifier".as_ref(),
        img.as_os_str(),
        // The image runs on the host here: written even when it does not fit the firmware
        // (another rate or full scale than the E-Core decoder's; the verdict is in the log).
        "--force".as_ref(),
        "--tune-on".as_ref(),
        vtune.as_os_str(),
        "--json".as_ref(),
        id_json.as_os_str(),
    ];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    eprintln!("{}: identify ...", fam.display());
    let t0 = Instant::now();
    run_host_sim(exe, &args, &dir.join("identify.log"))?;
    let identify_wall_s = t0.elapsed().as_secs_f64();
    let id = read_json(&id_json)?;

    // 2. static-test.
    let mut recs = Vec::new();
    for p in csvs(&stest)? {
        eprintln!("{}: replay", p.display());
        let (out_csv, out_json) = replay(exe, &img, &p, dir, "static", &[])?;
        let (drift_est, still) = read_replay_csv(&out_csv)?;
        let truth = read_truth(&p)?;
        if drift_est.len() != truth.len() {
            bail!(
                "{}: {} replay rows for {} samples",
                out_csv.display(),
                drift_est.len(),
                truth.len()
            );
        }
        let j = read_json(&out_json)?;
        recs.push((p, truth, drift_est, still, j));
    }
    let g = STATIC_Q_GRID;
    let rs: Vec<f64> = recs.iter().map(|r| diff_var_dps2(&r.1.rate_dps)).collect();
    let truths: Vec<&NavRecord> = recs.iter().map(|r| &r.1).collect();
    let picked = static_rw::pick_q(&truths)
        .ok_or_else(|| anyhow!("{}: no static-test score", stest.display()))?;
    let rw_run = |q: f64, i: usize| -> Vec<f64> { static_rw::estimate(&recs[i].1, q, rs[i]) };
    let rw_q = QPick::new(
        &nav::Tuning {
            q_dps2: picked.q_dps2,
            heading_rms_deg: picked.mean_e_truth,
            grid: picked.grid,
        },
        g,
    );

    // Self-calibrated filter: q tuned on the tune vehicles (its own detector).
    let tune_recs: Vec<NavRecord> = csvs(&vtune)?
        .iter()
        .map(|p| read_truth(p))
        .collect::<Result<_>>()?;
    let sg = SELFCAL_Q_GRID;
    let st = nav::tune_selfcal_q(
        &tune_recs,
        SelfCalConfig::with_q(0.0),
        &nav::log_grid(sg.0, sg.1, sg.2),
    )
    .ok_or_else(|| anyhow!("{}: no tune vehicle scored", vtune.display()))?;
    let selfcal_q = QPick::new(&st, sg);
    let selfcal = |r: &NavRecord| -> (nav::Run, SelfCalKalman) {
        let mut k = SelfCalKalman::new(SelfCalConfig::with_q(selfcal_q.q_dps2));
        let run = nav::run(r, &mut k, &[]);
        (run, k)
    };

    let mut srecs = Vec::new();
    for (i, (p, truth, drift_est, still, j)) in recs.iter().enumerate() {
        let (sc_run, sc) = selfcal(truth);
        srecs.push(StaticRecord {
            record: file_name(p),
            samples: truth.len(),
            rms_drift_dph: rms(truth.drift_dps.iter().copied()) * nav::DPH_PER_DPS,
            identifier_e_truth: e_truth(drift_est, &truth.drift_dps),
            identifier_still_fraction: fraction(still),
            replay_identifier_e_truth_dph: j["scores"]["rows"][0]["scores"]["e_truth_dph"].as_f64(),
            rw_kalman_r_dps2: rs[i],
            noise_x_image: spec_var_dps2(j).map(|v| (rs[i] / v).sqrt()),
            rw_kalman_e_truth: e_truth(&rw_run(rw_q.q_dps2, i), &truth.drift_dps),
            selfcal_e_truth: e_truth(&sc_run.drift_est_dps, &truth.drift_dps),
            selfcal_still_fraction: sc.still_samples() as f64 / sc.samples().max(1) as f64,
            selfcal_noise_var_dps2: sc.noise_var_dps2(),
        });
    }
    let mean_id = mean(srecs.iter().map(|r| r.identifier_e_truth));
    let mean_rw = mean(srecs.iter().map(|r| r.rw_kalman_e_truth));
    let static_test = StaticTest {
        mean_identifier_e_truth: mean_id,
        mean_identifier_still_fraction: mean(srecs.iter().map(|r| r.identifier_still_fraction)),
        mean_rw_kalman_e_truth: mean_rw,
        mean_selfcal_e_truth: mean(srecs.iter().map(|r| r.selfcal_e_truth)),
        goal_met: mean_id <= E_TRUTH_GOAL && mean_id < mean_rw,
        rw_kalman_q: rw_q,
        records: srecs,
    };

    // 3. vehicles-test.
    let mut vrecs = Vec::new();
    let (mut bq, mut bsrc) = (None, None);
    for p in csvs(&vtest)? {
        eprintln!("{}: replay", p.display());
        let (out_csv, out_json) = replay(
            exe,
            &img,
            &p,
            dir,
            "vehicle",
            &["--validate".as_ref(), vtune.as_os_str()],
        )?;
        let (_, still) = read_replay_csv(&out_csv)?;
        let j = read_json(&out_json)?;
        let truth = read_truth(&p)?;
        let rms_drift_dph = rms(truth.drift_dps.iter().copied()) * nav::DPH_PER_DPS;
        let scores = &j["scores"];
        bq = scores["baselines"]["q_dps2"].as_f64();
        bsrc = scores["baselines"]["q_source"].as_str().map(String::from);
        let mut rows: Vec<(String, f64, Option<f64>)> = scores["rows"]
            .as_array()
            .ok_or_else(|| anyhow!("{}: no scores.rows (no truth?)", out_json.display()))?
            .iter()
            .map(|r| {
                (
                    r["name"].as_str().unwrap_or("?").to_string(),
                    r["scores"]["heading_rms_deg"].as_f64().unwrap_or(f64::NAN),
                    r["scores"]["e_truth_dph"]
                        .as_f64()
                        .map(|e| e / rms_drift_dph),
                )
            })
            .collect();
        let (sc_run, sc) = selfcal(&truth);
        rows.push((
            format!("{} [q tuned on vehicles-tune]", nav::SELFCAL_LABEL),
            sc_run.scores.heading_rms_deg,
            sc_run.scores.e_truth_dph.map(|e| e / rms_drift_dph),
        ));
        let below = rows.split_first().is_some_and(|(id, rest)| {
            rest.iter()
                .filter(|r| r.0 != nav::NO_COMPENSATION)
                .all(|r| id.1 < r.1)
        });
        vrecs.push(VehicleRecord {
            record: file_name(&p),
            rows,
            truth_still_fraction: fraction(&truth.still_truth()),
            identifier_still_fraction: fraction(&still),
            noise_x_image: sc
                .noise_var_dps2()
                .zip(spec_var_dps2(&j))
                .map(|(a, b)| (a / b).sqrt()),
            detector_false_still_rate: scores["detector"]["false_still_rate"].as_f64(),
            detector_missed_still_rate: scores["detector"]["missed_still_rate"].as_f64(),
            selfcal_tuned_still_fraction: sc.still_samples() as f64 / sc.samples().max(1) as f64,
            identifier_below_every_baseline: below,
        });
    }
    let mean_heading_rms_deg = vrecs
        .first()
        .map(|f| {
            (0..f.rows.len())
                .map(|i| {
                    (
                        f.rows[i].0.clone(),
                        mean(
                            vrecs
                                .iter()
                                .map(|r| r.rows.get(i).map_or(f64::NAN, |x| x.1)),
                        ),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    let vehicles_test = VehiclesTest {
        identifier_best: vrecs
            .iter()
            .filter(|r| r.identifier_below_every_baseline)
            .count(),
        records: vrecs,
        mean_heading_rms_deg,
        baseline_q_dps2: bq,
        baseline_q_source: bsrc,
        selfcal_q,
    };
    Ok(Family {
        family: fam.display().to_string(),
        host_sim: exe.display().to_string(),
        identify_args: extra.to_vec(),
        identify_wall_s,
        train_records: csvs(&train)?.len(),
        tune_vehicles: tune_recs.len(),
        identify_tuning: id["tuning"].clone(),
        identify_tuning_text: id["tuning"]["picked"].as_object().map(|p| {
            format!(
                "links' spread x{}, Gauss-Markov sigmas x{}, correlation time {} s (null: as fitted) ({} deg on the tune vehicles)",
                p["link_scale"], p["markov_scale"], p["markov_tau_s"], p["heading_rms_deg"]
            )
        }),
        static_test,
        vehicles_test,
    })
}

/// Short column names of the known rows.
fn short(name: &str) -> String {
    let known = [
        ("motion identifier", "identifier"),
        (nav::NO_COMPENSATION, "none"),
        ("alignment bias", "align"),
        ("gated random-walk Kalman", "ZARU"),
        ("gated Kalman + temperature", "ZARU+T"),
    ];
    if name.starts_with(nav::SELFCAL_LABEL) {
        return if name.len() > nav::SELFCAL_LABEL.len() {
            "own-det*".into()
        } else {
            "own-det".into()
        };
    }
    known
        .iter()
        .find(|(k, _)| name.starts_with(k))
        .map_or_else(|| name.chars().take(10).collect(), |(_, s)| s.to_string())
}

fn print_family(f: &Family) {
    println!(
        "\n== family {} ({} train records, {} tune vehicles; identify {:.1} s wall{})",
        f.family,
        f.train_records,
        f.tune_vehicles,
        f.identify_wall_s,
        if f.identify_args.is_empty() {
            String::new()
        } else {
            format!(", extra args {:?}", f.identify_args)
        }
    );
    if let Some(t) = &f.identify_tuning_text {
        println!("identify --tune-on picked: {t}");
    }
    let s = &f.static_test;
    println!("static-test: e_truth = RMS(est - drift) / RMS(drift) (no compensation 1.000); still = fraction flagged still");
    println!(
        "{:<18} {:>7} {:>9} {:>10} {:>8} {:>13} {:>10} {:>8}",
        "record", "noise", "drift", "identifier", "still", "RW-KF all", "own-det*", "still"
    );
    println!(
        "{:<18} {:>7} {:>9} {:>10} {:>8} {:>13} {:>10} {:>8}",
        "", "x image", "RMS deg/h", "e_truth", "", "still e_truth", "e_truth", ""
    );
    for r in &s.records {
        println!(
            "{:<18} {:>6} {:>9.2} {:>10.3} {:>7.1}% {:>13.3} {:>10.3} {:>7.1}%",
            r.record,
            r.noise_x_image.map_or("-".into(), |x| format!("{x:.2}")),
            r.rms_drift_dph,
            r.identifier_e_truth,
            100.0 * r.identifier_still_fraction,
            r.rw_kalman_e_truth,
            r.selfcal_e_truth,
            100.0 * r.selfcal_still_fraction
        );
    }
    println!(
        "{:<18} {:>7} {:>9} {:>10.3} {:>7.1}% {:>13.3} {:>10.3}",
        "mean",
        "",
        "",
        s.mean_identifier_e_truth,
        100.0 * s.mean_identifier_still_fraction,
        s.mean_rw_kalman_e_truth,
        s.mean_selfcal_e_truth
    );
    println!(
        "RW-KF all still: r = var(diff)/2 of each record, {} tuned on these records (least mean e_truth)",
        s.rw_kalman_q.text()
    );
    println!(
        "goal (identifier e_truth <= {E_TRUTH_GOAL:.2} and below the tuned RW-KF): {} ({:.3} vs {:.3})",
        if s.goal_met { "MET" } else { "NOT MET" },
        s.mean_identifier_e_truth,
        s.mean_rw_kalman_e_truth
    );
    let v = &f.vehicles_test;
    println!("vehicles-test: heading-error RMS, deg");
    let names: Vec<String> = v.mean_heading_rms_deg.iter().map(|m| short(&m.0)).collect();
    let mut head = format!("{:<18}", "record");
    for n in &names {
        head += &format!(" {n:>10}");
    }
    println!(
        "{head} {:>6} {:>6} {:>6} {:>6}",
        "noise", "still", "still", "still"
    );
    println!(
        "{:<18}{} {:>6} {:>6} {:>6} {:>6}",
        "",
        " ".repeat(11 * names.len()),
        "x img",
        "truth",
        "id",
        "own*"
    );
    for r in &v.records {
        let mut line = format!("{:<18}", r.record);
        for x in &r.rows {
            line += &format!(" {:>10.4}", x.1);
        }
        println!(
            "{line} {:>6} {:>5.1}% {:>5.1}% {:>5.1}%{}",
            r.noise_x_image.map_or("-".into(), |x| format!("{x:.2}")),
            100.0 * r.truth_still_fraction,
            100.0 * r.identifier_still_fraction,
            100.0 * r.selfcal_tuned_still_fraction,
            if r.identifier_below_every_baseline {
                "  identifier best"
            } else {
                ""
            }
        );
    }
    let mut line = format!("{:<18}", "mean");
    for m in &v.mean_heading_rms_deg {
        line += &format!(" {:>10.4}", m.1);
    }
    println!("{line}");
    println!(
        "baselines (align..own-det): q {} from {}; own-det*: own detector, {} tuned on vehicles-tune (least mean heading RMS)",
        v.baseline_q_dps2.map_or("-".into(), |q| format!("{q:.2e}")),
        v.baseline_q_source.as_deref().unwrap_or("-"),
        v.selfcal_q.text()
    );
    println!(
        "the identifier is below every causal baseline on {} of {} test vehicles",
        v.identifier_best,
        v.records.len()
    );
}
