//! `host-sim demo --out DIR`: the project's main job with nothing to configure.
//!
//! 1. Simulates an E-Core 2000-like static gyro with the built-in preset
//!    (`host-sim/presets/ecore2000.toml`) at [`RATE_HZ`] Hz for [`DURATION_S`] s, seed
//!    [`SEED`], and writes it as E-Core binary frames, `DIR/record.bin` (60 deg/s full
//!    scale: the preset's rate is already quantized to counts, so nothing is lost).
//! 2. Replays `DIR/record.bin` through the fog-core pipeline with exactly the code of
//!    `host-sim replay --format ecore-bin` (default `level-trend` identifier), writing
//!    `DIR/replay.csv`.
//! 3. Writes the report in `DIR` ([`crate::report`]): `index.html`, the SVG figures and
//!    `summary.json`. The true drift of every sample comes from a second simulator with the
//!    same model and seed run in step (the simulator is deterministic), so memory stays
//!    constant. The same record with its truth as CSV:
//!    `host-sim simulate --preset ecore2000 --duration-s 1800 --seed 1 --output rec.csv`.

use crate::record;
use crate::replay::stream::{self as replay_cmd, IdPreset, InputFormat, Options, Outcome};
use crate::report;
use crate::sim::{self, Simulator};
use crate::simulate_cmd;
use anyhow::{Context, Result};
use fog_core::frame::ecore;
use std::io::Write;
use std::path::PathBuf;

/// Seed of the demo record.
pub const SEED: u64 = 1;
/// Length of the demo record, s (the paper's records are 30 min).
pub const DURATION_S: f64 = 1800.0;
/// Sample rate, Hz.
pub const RATE_HZ: f64 = 100.0;
/// Built-in model.
pub const PRESET: &str = "ecore2000";

/// Arguments of `host-sim demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder to write (created if missing; its demo files are replaced).
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    let dir = &args.out;
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the output folder", dir.display()))?;
    let model = sim::preset(PRESET)?;
    let full_scale_dps = model.full_scale_dps.unwrap_or(60.0);
    let bin = dir.join("record.bin");
    let mut simulator = Simulator::new(&model, SEED, RATE_HZ)?;
    let mut n = 0u64;
    record::write_atomic(&bin, |w| {
        loop {
            let s = simulator.next_sample();
            if s.t_s >= DURATION_S {
                break;
            }
            let frame = ecore::encode(simulate_cmd::counts(s.rate_dps, full_scale_dps), [0; 4]);
            w.write_all(&frame)
                .with_context(|| format!("{}: write failed", bin.display()))?;
            n += 1;
        }
        Ok(())
    })?;
    eprintln!(
        "demo: simulated {n} samples ({DURATION_S} s at {RATE_HZ} Hz, preset {PRESET}, seed {SEED}) -> {}",
        bin.display()
    );
    let mut truth_sim = Simulator::new(&model, SEED, RATE_HZ)?;
    let mut truth = move || truth_sim.next_sample().drift_dps;
    let opts = Options {
        format: InputFormat::EcoreBin,
        full_scale_dps: full_scale_dps as f32,
        rate_hz: RATE_HZ,
        preset: IdPreset::LevelTrend,
        collect: true,
    };
    let out_csv = dir.join("replay.csv");
    let Outcome {
        mut summary,
        collector,
    } = replay_cmd::replay(
        &bin,
        &out_csv,
        &opts,
        Some(&mut truth),
        &format!("the simulator (preset {PRESET}, seed {SEED}) run in step"),
    )?;
    replay_cmd::print_summary(&summary)?;
    let c = collector.context("demo: the report's data were not collected")?;
    let index = report::write(dir, &mut summary, &c)?;
    println!("{}", index.display());
    Ok(())
}
