//! `host-sim image`: what an identifier image (`.fogi`) holds ([`crate::motion::show`]) and
//! what the firmware does with it ([`crate::firmware_fit`]); or, `--gyro`, the image a gyro
//! file stands for (its `[identified]` model, else its datasheet part alone: what `replay
//! --gyro` runs), before any image is written.

use crate::gyro::Gyro;
use crate::motion::show;
use crate::record;
use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;
use fog_core::image::Image;
use std::path::PathBuf;

/// Arguments of `host-sim image`.
#[derive(Parser, Debug, Clone)]
pub struct Args {
    /// The identifier image (`identify --save-identifier`, `demo`'s `identifier.fogi`, the
    /// firmware's `fog-firmware/identifier/default.fogi`).
    #[arg(long, required_unless_present = "gyro", conflicts_with = "gyro")]
    pub input: Option<PathBuf>,
    /// Instead of `--input`: the image of a gyro (a built-in's name or a gyro file,
    /// host_sim::gyro): its `[identified]` model, else the model of its datasheet part
    /// alone, the filter at its default settings.
    #[arg(long, value_name = "NAME|FILE")]
    pub gyro: Option<String>,
    /// Also write the description as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs the command: the description on stdout, what the firmware does with the image on
/// stderr ([`crate::firmware_fit`]: the verdict first), both in the JSON. An image that
/// does not fit (its set-up refuses it, or it does not run as the unit needs): the same
/// lines and the JSON (with the same verdict and reasons), then an error naming the image
/// and the verdict (non-zero exit).
pub fn run(a: &Args) -> Result<()> {
    let (name, input, bytes, image) = match (&a.input, &a.gyro) {
        (Some(p), _) => {
            let bytes =
                std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))?;
            let image = Image::parse(&bytes).map_err(|e| anyhow!("{}: {e}", p.display()))?;
            (p.display().to_string(), Some(p.clone()), bytes, image)
        }
        (None, Some(arg)) => {
            let g = Gyro::from_arg(arg)?;
            let image = g.image()?;
            let bytes =
                crate::motion::image_bytes(&image).map_err(|e| anyhow!("{}: {e}", g.source))?;
            eprintln!("{}: the image of {}", g.source, g.image_words());
            (g.source.clone(), g.path.clone(), bytes, image)
        }
        (None, None) => bail!("give --input F.fogi or --gyro NAME|FILE"),
    };
    let info = show::describe(&image, &bytes);
    print!("{}", show::text(&name, &info));
    eprint!("{}", info.firmware.text());
    if let Some(j) = &a.json {
        if let Some(i) = &input {
            record::refuse_overwrite(i, j)?;
        }
        let text = serde_json::to_string_pretty(&info)?;
        record::write_atomic(j, |w| {
            std::io::Write::write_all(w, text.as_bytes())
                .with_context(|| format!("{}: write failed", j.display()))
        })?;
    }
    if !info.firmware.fits {
        bail!(
            "{}: the image does not fit the firmware: {}",
            name,
            info.firmware.why()
        );
    }
    Ok(())
}
