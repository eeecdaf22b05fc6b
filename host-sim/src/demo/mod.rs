//! `host-sim demo`: train at rest, compensate in motion, score against the baselines.
//!
//! 1. A gyro family from the built-in `ecore2000` preset with `[family]` unit spread
//!    [`UNIT_SPREAD`] and per-record temperature (ambient start uniform in
//!    [`INITIAL_C_RANGE`], self-heating in [`WARMUP_RISE_C_RANGE`]): ASSUMED values of this
//!    demo, not a measured family.
//! 2. Fits the gyro model on `train_records` static records of that family (units 1..,
//!    record seeds 101..; [`crate::gyro_fit`]).
//! 3. Tunes the gated Kalman baseline's q on `validate_records` simulated `vehicle` records
//!    of other units ([`nav::tune_gated_q`], truth still flags, [`BASELINE_Q_GRID`]), and
//!    the model's two scales on the same records ([`motion::tune`], the filter's own test),
//!    then writes the image `DIR/identifier.fogi`. A pick at an end of a grid is printed
//!    (and, for the baseline, written into its label; never silent).
//! 4. Simulates one `vehicle` record (unit [`VEHICLE_UNIT`], seed [`VEHICLE_SEED`]), writes
//!    it as `DIR/vehicle.csv`, replays it with the identifier ([`crate::replay::motion`]),
//!    `DIR/replay.csv`, scores `test_records` vehicle records (the replayed one first) and
//!    writes the report (`index.html`, heading-error figure with the identifier beside the
//!    baselines, `summary.json`). Printed and in `index.html`, the result comes first: the
//!    pooled mean over the test vehicles against each baseline and the verdict
//!    ([`crate::replay::pooled`]); the replayed record, one draw, after it.

use crate::identify::series::{Records, Series};
use crate::motion::tune::{self, run_image};
use crate::motion::{self, TrainOptions};
use crate::nav::BaselineConfig;
use crate::nav::{self, NavRecord};
use crate::record;
use crate::replay::motion::{replay, MotionOptions, TestSet};
use crate::replay::stream::{IdPreset, InputFormat, Options};
use crate::report;
use crate::sim::{self, Model, Profile, Simulator};
use crate::simulate_cmd::{write_csv_row, CSV_HEADER_MOVING};
use anyhow::{Context, Result};
use fog_core::image::Image;
use fog_core::sensor::SensorConfig;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Built-in model.
pub const PRESET: &str = "ecore2000";
/// Sample rate, Hz.
pub const RATE_HZ: f64 = 100.0;
/// Relative 1-sigma spread of the units' thermal and warm-up coefficients (ASSUMED).
pub const UNIT_SPREAD: f64 = 0.2;
/// Ambient temperature at power-on, deg C, uniform per record (ASSUMED).
pub const INITIAL_C_RANGE: [f64; 2] = [10.0, 35.0];
/// Self-heating after power-on, deg C, uniform per record (ASSUMED).
pub const WARMUP_RISE_C_RANGE: [f64; 2] = [2.0, 8.0];
/// Initial still (alignment) period of the vehicle records, s.
pub const ALIGN_S: f64 = 120.0;
/// Unit of the replayed vehicle record (not a training unit).
pub const VEHICLE_UNIT: u64 = 900;
/// Seed of the replayed vehicle record.
pub const VEHICLE_SEED: u64 = 7;

/// The gated Kalman baseline's q grid, (deg/s)^2 per sample: (low, high, points per decade).
pub const BASELINE_Q_GRID: (f64, f64, usize) = (1e-16, 1e-8, 4);

/// `" (AT THE LOW END OF ITS GRID)"` / `" (AT THE HIGH END ...)"` / `""`.
pub fn grid_end_note(grid: &[f64], picked: f64) -> &'static str {
    let at = |v: Option<&f64>| v.is_some_and(|&g| (picked / g - 1.0).abs() < 1e-9);
    if grid.len() > 1 && at(grid.first()) {
        " (AT THE LOW END OF ITS GRID)"
    } else if grid.len() > 1 && at(grid.last()) {
        " (AT THE HIGH END OF ITS GRID)"
    } else {
        ""
    }
}

/// What the demo runs.
#[derive(Debug, Clone)]
pub struct DemoConfig {
    /// Static training records.
    pub train_records: u64,
    /// Vehicle records on which the baseline's q and the identifier's level are tuned.
    pub validate_records: u64,
    /// Length of every record, s.
    pub duration_s: f64,
    /// Test vehicle records (units [`VEHICLE_UNIT`].., seeds [`VEHICLE_SEED`]..; the first
    /// is the replayed record) scored beside the baselines.
    pub test_records: u64,
}

impl DemoConfig {
    /// The demo: 12 training records, 32 tune and 32 test vehicle records, 1800 s
    /// each. Why 32: the mean heading RMS of one tuned model was 0.1963 and 0.1311 deg on
    /// two sets of 8 vehicles of the same family, 0.1534 and 0.1540 on two sets of 32
    /// (docs/motion.md, "How many vehicles a comparison needs").
    pub fn full() -> Self {
        Self {
            train_records: 12,
            validate_records: 32,
            duration_s: 1800.0,
            test_records: 32,
        }
    }

    /// The CI variant (`--quick`): 12 training records, 2 tune and 2 test records,
    /// 600 s each.
    pub fn quick() -> Self {
        Self {
            validate_records: 2,
            duration_s: 600.0,
            test_records: 2,
            ..Self::full()
        }
    }
}

/// A unit of the demo's family; `vehicle`: the `vehicle` motion profile, else static.
pub fn family_model(unit: u64, vehicle: bool) -> Result<Model> {
    let mut m = sim::preset(PRESET)?;
    m.family.unit_seed = Some(unit);
    m.family.unit_spread = UNIT_SPREAD;
    m.family.initial_c_range = Some(INITIAL_C_RANGE);
    m.family.warmup_rise_c_range = Some(WARMUP_RISE_C_RANGE);
    if vehicle {
        m.motion.profile = Profile::Vehicle;
        m.motion.vehicle.align_s = ALIGN_S;
    }
    Ok(m)
}

/// `duration_s` of `model` at [`RATE_HZ`], seed `seed`.
pub fn samples(model: &Model, seed: u64, duration_s: f64) -> Result<Vec<sim::Sample>> {
    let mut s = Simulator::new(model, seed, RATE_HZ)?;
    let mut out = Vec::with_capacity((duration_s * RATE_HZ) as usize);
    loop {
        let x = s.next_sample();
        if x.t_s >= duration_s {
            return Ok(out);
        }
        out.push(x);
    }
}

/// The demo's static training records (units 1..=n, seeds 101.., `duration_s` each at
/// [`RATE_HZ`], the family of [`family_model`]), simulated on demand.
pub struct TrainingSet {
    /// Number of records.
    pub n: u64,
    /// Length of each record, s.
    pub duration_s: f64,
}

impl Records for TrainingSet {
    fn len(&self) -> usize {
        self.n as usize
    }
    fn get(&self, i: usize) -> Result<Series> {
        static_run(i as u64 + 1, 101 + i as u64, self.duration_s)
    }
}

/// One static run of the family's unit `unit` (a power-on: its seed draws the noise,
/// turn-on and conditions), `duration_s` at [`RATE_HZ`], with its drift and temperature.
pub fn static_run(unit: u64, seed: u64, duration_s: f64) -> Result<Series> {
    let x = samples(&family_model(unit, false)?, seed, duration_s)?;
    Ok(Series {
        name: format!("{PRESET} unit {unit} seed {seed} (static)"),
        t_s: x.iter().map(|s| s.t_s).collect(),
        rate_dps: x.iter().map(|s| s.rate_dps as f32).collect(),
        drift_dps: Some(x.iter().map(|s| s.drift_dps as f32).collect()),
        temp_c: Some(x.iter().map(|s| s.temp_c as f32).collect()),
        ..Default::default()
    })
}

fn write_csv(path: &Path, x: &[sim::Sample]) -> Result<()> {
    record::write_atomic(path, |w| {
        let io = |e: std::io::Error| anyhow::anyhow!("{}: write failed: {e}", path.display());
        writeln!(w, "{CSV_HEADER_MOVING}").map_err(io)?;
        for s in x {
            write_csv_row(w, s, true).map_err(io)?;
        }
        Ok(())
    })
}

/// Runs the demo into `dir`; returns the path of `index.html`.
pub fn run(dir: &Path, cfg: &DemoConfig) -> Result<PathBuf> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the output folder", dir.display()))?;
    let sensor = SensorConfig::ECORE_2000;
    let set = TrainingSet {
        n: cfg.train_records,
        duration_s: cfg.duration_s,
    };
    let train_options = TrainOptions::new(sensor);
    let trained = motion::train(&set, &train_options)?;
    let image = trained.image;
    let fogi = dir.join("identifier.fogi");
    eprintln!(
        "demo: fitted the gyro model on {} static {PRESET} records ({} s, unit spread {UNIT_SPREAD}, start {} to {} deg C, self-heating {} to {} deg C) -> {}",
        cfg.train_records,
        cfg.duration_s,
        INITIAL_C_RANGE[0],
        INITIAL_C_RANGE[1],
        WARMUP_RISE_C_RANGE[0],
        WARMUP_RISE_C_RANGE[1],
        fogi.display()
    );
    let mut val = Vec::new();
    for i in 0..cfg.validate_records {
        let x = samples(&family_model(800 + i, true)?, 201 + i, cfg.duration_s)?;
        val.push(NavRecord::from_samples(&x));
    }
    let r_dps2 = f64::from(sensor.sample_var_dps2());
    let (lo, hi, per) = BASELINE_Q_GRID;
    let baseline_grid = nav::log_grid(lo, hi, per);
    let tuned =
        nav::tune_gated_q(&val, r_dps2, &baseline_grid).context("demo: no tune vehicle record")?;
    let baseline_note = grid_end_note(&baseline_grid, tuned.q_dps2);
    // The model's two least certain numbers, tuned on the same records.
    let (image, tuning) = tune::tune(&image, &val)?;
    // What the firmware does with the image: printed after the result.
    let firmware = motion::write_image(&fogi, &image, false)?;
    eprintln!("demo: {}", tune::describe(&tuning));
    eprintln!(
        "demo: gated Kalman q {:.3e} (deg/s)^2 per sample{baseline_note} ({:.4} deg on the tune vehicles, truth still flags)",
        tuned.q_dps2, tuned.heading_rms_deg
    );
    if !baseline_note.is_empty() {
        eprintln!("demo: WARNING: the baseline's q is{baseline_note}: the grid does not bracket the optimum");
    }
    let vehicle = dir.join("vehicle.csv");
    let x = samples(
        &family_model(VEHICLE_UNIT, true)?,
        VEHICLE_SEED,
        cfg.duration_s,
    )?;
    write_csv(&vehicle, &x)?;
    eprintln!(
        "demo: simulated a {} s vehicle record (unit {VEHICLE_UNIT}, seed {VEHICLE_SEED}) -> {}",
        cfg.duration_s,
        vehicle.display()
    );
    let o = MotionOptions {
        identifier: Some(fogi),
        sensor: None,
        gyro_image: None,
        stream: Options {
            format: InputFormat::Csv,
            full_scale_dps: 0.0,
            rate_hz: 0.0,
            preset: IdPreset::LevelTrend,
            collect: false,
        },
        csv: crate::record::ReadOptions::default(),
        baseline_q: Some((
            tuned.q_dps2,
            format!(
                "tuned on {} tune vehicle records (units 800.., truth still flags){baseline_note}",
                val.len()
            ),
        )),
        validate: Vec::new(),
        figures: true,
    };
    let mut out = replay(&vehicle, &dir.join("replay.csv"), &o)?;
    let cmp = BaselineConfig {
        q_dps2: tuned.q_dps2,
        q_source: format!(
            "tuned on {} tune vehicle records (units 800.., truth still flags){baseline_note}",
            val.len()
        ),
        r_dps2,
        release_samples: crate::replay::motion::release_samples(&image),
    };
    let set = test_set(&image, cfg, &cmp)?;
    // The result first (pooled over every test vehicle), then the one example record.
    print_test_set(&set);
    eprintln!(
        "demo: example record: the first test vehicle (unit {VEHICLE_UNIT}, seed {VEHICLE_SEED}), one draw of the {}:",
        cfg.test_records
    );
    crate::replay::motion::print_summary(&out.summary)?;
    for line in firmware.text().lines() {
        eprintln!("demo: {line}");
    }
    out.summary.test_set = Some(set);
    out.summary.level_tuning = Some(tuning);
    out.summary.firmware = Some(firmware);
    report::motion::write(dir, &out)
}

/// The identifier and the baselines on `cfg.test_records` vehicle records (units
/// [`VEHICLE_UNIT`].., seeds [`VEHICLE_SEED`]..), each with the identifier's still flags as
/// in the replay.
fn test_set(image: &Image, cfg: &DemoConfig, cmp: &BaselineConfig) -> Result<TestSet> {
    let mut tables = Vec::new();
    for i in 0..cfg.test_records {
        let x = samples(
            &family_model(VEHICLE_UNIT + i, true)?,
            VEHICLE_SEED + i,
            cfg.duration_s,
        )?;
        let rec = NavRecord::from_samples(&x);
        let (drift, still) = run_image(image, &rec)?;
        tables
            .push(nav::compare(&rec, "motion identifier", &drift, &still, true, cmp.clone()).table);
    }
    Ok(TestSet::new(
        format!(
            "{} vehicle records of {} s (units {VEHICLE_UNIT}..{}, seeds {VEHICLE_SEED}..{}; the first is the replayed record)",
            cfg.test_records,
            cfg.duration_s,
            VEHICLE_UNIT + cfg.test_records.saturating_sub(1),
            VEHICLE_SEED + cfg.test_records.saturating_sub(1)
        ),
        &tables,
    ))
}

fn print_test_set(set: &TestSet) {
    for line in set.text().lines() {
        eprintln!("demo: {line}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_ends_are_named() {
        let g = nav::log_grid(1e-16, 1e-8, 4);
        assert_eq!(grid_end_note(&g, 1e-16), " (AT THE LOW END OF ITS GRID)");
        assert_eq!(
            grid_end_note(&g, g[g.len() - 1]),
            " (AT THE HIGH END OF ITS GRID)"
        );
        assert_eq!(grid_end_note(&g, g[3]), "");
        assert_eq!(grid_end_note(&[1.0], 1.0), "");
    }
}
