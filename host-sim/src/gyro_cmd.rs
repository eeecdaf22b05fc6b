//! `host-sim gyro`: the gyro file ([`crate::gyro`]): `convert` an old sensor or model file,
//! `show` a built-in (a commented file to start from) or what a file gives each command.

use crate::gyro::{self, convert, Gyro};
use crate::record;
use anyhow::{Context, Result};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `host-sim gyro`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to do.
    #[command(subcommand)]
    pub cmd: Cmd,
}

/// `host-sim gyro` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Cmd {
    /// Convert an old sensor file (`noise_density_deg_rth`), an old model file (`[noise]
    /// arw_dps_per_rthz`, deg/s units), or one of each (merged) into one gyro file; the
    /// converted file gives the same model bit for bit.
    Convert(ConvertArgs),
    /// Print a built-in gyro file (with its comments: a file to start from), or a gyro
    /// file as the reader takes it, with what identify, replay and image get from it.
    Show(ShowArgs),
}

/// `host-sim gyro convert`.
#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// The old file(s): a sensor file, a model file, or one of each.
    #[arg(long, num_args = 1..=2, required = true)]
    pub input: Vec<PathBuf>,
    /// The gyro file to write.
    #[arg(long)]
    pub output: PathBuf,
}

/// `host-sim gyro show`.
#[derive(clap::Args, Debug)]
pub struct ShowArgs {
    /// A built-in's name or a gyro file.
    #[arg(value_name = "NAME|FILE")]
    pub gyro: String,
}

/// Runs `host-sim gyro`.
pub fn run(a: &Args) -> Result<()> {
    match &a.cmd {
        Cmd::Convert(c) => run_convert(c),
        Cmd::Show(s) => run_show(s),
    }
}

fn run_convert(a: &ConvertArgs) -> Result<()> {
    let inputs: Vec<&std::path::Path> = a.input.iter().map(PathBuf::as_path).collect();
    record::refuse_overwrite_all(&inputs, &[a.output.as_path()])?;
    let text = convert::convert(&inputs, &a.output)?;
    record::write_atomic(&a.output, |w| {
        w.write_all(text.as_bytes())
            .with_context(|| format!("{}: write failed", a.output.display()))
    })?;
    let names: Vec<String> = a.input.iter().map(|p| p.display().to_string()).collect();
    eprintln!(
        "{} -> {} (gyro file)",
        names.join(" + "),
        a.output.display()
    );
    Ok(())
}

fn run_show(a: &ShowArgs) -> Result<()> {
    if let Some((_, _, text)) = gyro::BUILTIN.iter().find(|b| b.0 == a.gyro) {
        print!("{text}");
        return Ok(());
    }
    let g = Gyro::from_arg(&a.gyro)?;
    let parts = gyro::write::Parts {
        header: vec![format!("{} as host-sim reads it", g.source)],
        name: &g.name,
        model: g.model.clone(),
        drift_bound_dps: g.drift_bound_dps,
        temperature_column: g.temperature_column.as_deref(),
        identified: g.identified,
    };
    print!("{}", gyro::write::text(&parts)?);
    match g.sensor() {
        Ok(s) => eprintln!(
            "{}: identify, replay and image take: {} Hz, full scale {} deg/s, quantum {} deg/s, white noise {:.6} deg/sqrt(h), drift bound {:.6} deg/h; drift filter model: {}",
            g.source,
            s.config.sample_rate_hz,
            s.config.full_scale_dps,
            s.config.quantum_dps,
            f64::from(s.config.noise_density_dps_rthz) * gyro::units::DEG_RTH,
            f64::from(s.config.drift_bound_dps) * gyro::units::DPH,
            g.image_words()
        ),
        Err(e) => eprintln!("{}: not for identify, replay or image: {e:#}", g.source),
    }
    Ok(())
}
