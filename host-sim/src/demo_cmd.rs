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
    /// Records of 600 s instead of 1800 s, 2 validation and 2 test vehicles instead of 32
    /// each (the CI test's variant).
    #[arg(long)]
    pub quick: bool,
    /// The bench trainer of the model (`identify --preset motion --motion-trainer`).
    #[arg(long, value_enum, default_value_t = crate::motion::TrainerArg::DrlsChecked)]
    pub trainer: crate::motion::TrainerArg,
    /// The identifier's candidate arrangements (`identify --preset motion --level-update
    /// A B --tune-on`): each tuned on the validation vehicles from its default Gauss-Markov
    /// state or bank, the best kept (default: the product's, dual-thermal).
    #[arg(long, value_enum, num_args = 1.., default_values_t = demo::DEFAULT_ARRANGEMENTS.map(crate::motion::LevelUpdateArg::of))]
    pub level_update: Vec<crate::motion::LevelUpdateArg>,
}

/// Runs the command; prints the path of `index.html` on stdout.
pub fn run(args: &Args) -> Result<()> {
    let mut cfg = if args.quick {
        DemoConfig::quick()
    } else {
        DemoConfig::full()
    };
    cfg.trainer = args.trainer;
    cfg.arrangements = args.level_update.iter().map(|l| l.arrangement()).collect();
    let index = demo::run(&args.out, &cfg)?;
    println!("{}", index.display());
    Ok(())
}
