//! `host-sim reproduce`: the paper's section 5 experiment on simulated records
//! (see [`crate::identify::repro`] for the conditions).

use crate::identify::repro::{Group, SimRecords};
use crate::identify::{self, Report};
use crate::identify_cmd::{options, write_report, IdentifierArgs};
use anyhow::{bail, Result};
use serde::Serialize;
use std::path::PathBuf;

/// Arguments of `host-sim reproduce`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Condition set.
    #[arg(long, value_enum, default_value_t = Group::Nominal)]
    pub group: Group,
    /// Records in all (the paper: 265).
    #[arg(long, default_value_t = 265)]
    pub records: usize,
    /// Of which for training (the paper: 180); the rest validate.
    #[arg(long, alias = "train", default_value_t = 180)]
    pub train_records: usize,
    /// Duration of each record, s (the paper: 1800).
    #[arg(long, default_value_t = 1800.0)]
    pub duration_s: f64,
    /// Identifier options.
    #[command(flatten)]
    pub id: IdentifierArgs,
    /// JSON report to write (default: on stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// The report: the identify report plus the experiment's shape.
#[derive(Serialize)]
struct ReproReport<'a> {
    group: Group,
    records: usize,
    duration_s: f64,
    #[serde(flatten)]
    report: &'a Report,
}

/// Runs the command.
pub fn run(a: &Args) -> Result<()> {
    if a.train_records == 0 || a.train_records >= a.records {
        bail!(
            "--train-records must be between 1 and --records - 1 ({} given for {} records)",
            a.train_records,
            a.records
        );
    }
    if !(a.duration_s >= 60.0 && a.duration_s.is_finite()) {
        bail!("--duration-s must be at least 60");
    }
    let train = SimRecords::new(a.group, 0, a.train_records, a.duration_s)?;
    let validate = SimRecords::new(
        a.group,
        a.train_records,
        a.records - a.train_records,
        a.duration_s,
    )?;
    let report = identify::run(&options(&a.id), &train, &validate)?;
    write_report(
        a.json.as_deref(),
        &ReproReport {
            group: a.group,
            records: a.records,
            duration_s: a.duration_s,
            report: &report,
        },
        &report,
    )
}
