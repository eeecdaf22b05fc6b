//! `host-sim demo --report DIR [--quick]`: the project's main job with nothing to configure,
//! run by [`crate::demo`] (fit the gyro model on simulated static records, replay a
//! simulated vehicle record, report the identifier beside the causal baselines).

use crate::demo::{self, DemoConfig};
use anyhow::Result;
use std::path::PathBuf;

/// Arguments of `host-sim demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Report folder to write (created if missing; its demo files are replaced).
    #[arg(long, alias = "out", value_name = "DIR")]
    pub report: PathBuf,
    /// Records of 600 s instead of 1800 s, 2 tune and 2 test vehicles instead of 32
    /// each (the CI test's variant).
    #[arg(long)]
    pub quick: bool,
}

/// Runs the command; prints the path of `index.html` on stdout.
pub fn run(args: &Args) -> Result<()> {
    let cfg = if args.quick {
        DemoConfig::quick()
    } else {
        DemoConfig::full()
    };
    let index = demo::run(&args.report, &cfg)?;
    println!("{}", index.display());
    Ok(())
}
