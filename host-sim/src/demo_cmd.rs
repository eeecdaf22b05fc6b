//! `host-sim demo --out DIR [--quick]`: the project's main job with nothing to configure,
//! run by [`crate::demo`] (train the motion identifier on simulated static records, replay a
//! simulated vehicle record, report the identifier beside the causal baselines).

use crate::demo::{self, DemoConfig};
use anyhow::Result;
use std::path::PathBuf;

/// Arguments of `host-sim demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder to write (created if missing; its demo files are replaced).
    #[arg(long)]
    pub out: PathBuf,
    /// Records of 600 s instead of 1800 s and one validation record (the CI test's variant).
    #[arg(long)]
    pub quick: bool,
    /// Shrink the trained model by leave-one-record-out (`identify --preset motion
    /// --shrink`; not the firmware's default).
    #[arg(long)]
    pub shrink: bool,
    /// The bench trainer of the model (`identify --preset motion --motion-trainer`).
    #[arg(long, value_enum, default_value_t = crate::motion::TrainerArg::DrlsChecked)]
    pub trainer: crate::motion::TrainerArg,
    /// How the identifier's level learns (`identify --preset motion --level-update`), with
    /// that arrangement's default Gauss-Markov state or bank.
    #[arg(long, value_enum, default_value_t = crate::motion::LevelUpdateArg::default())]
    pub level_update: crate::motion::LevelUpdateArg,
}

/// Runs the command; prints the path of `index.html` on stdout.
pub fn run(args: &Args) -> Result<()> {
    let mut cfg = if args.quick {
        DemoConfig::QUICK
    } else {
        DemoConfig::FULL
    };
    cfg.shrink = args.shrink;
    cfg.trainer = args.trainer;
    cfg.arrangement = args.level_update.arrangement();
    let index = demo::run(&args.out, &cfg)?;
    println!("{}", index.display());
    Ok(())
}
