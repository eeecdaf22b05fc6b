//! `host-sim image`: what an identifier image (`.fogi`) holds ([`crate::motion::show`]) and
//! what the firmware does with it ([`crate::firmware_fit`]).

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
    #[arg(long)]
    pub input: PathBuf,
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
    let bytes =
        std::fs::read(&a.input).with_context(|| format!("{}: cannot read", a.input.display()))?;
    let image = Image::parse(&bytes).map_err(|e| anyhow!("{}: {e}", a.input.display()))?;
    let info = show::describe(&image, &bytes);
    print!("{}", show::text(&a.input.display().to_string(), &info));
    eprint!("{}", info.firmware.text());
    if let Some(j) = &a.json {
        record::refuse_overwrite(&a.input, j)?;
        let text = serde_json::to_string_pretty(&info)?;
        record::write_atomic(j, |w| {
            std::io::Write::write_all(w, text.as_bytes())
                .with_context(|| format!("{}: write failed", j.display()))
        })?;
    }
    if !info.firmware.fits {
        bail!(
            "{}: the image does not fit the firmware: {}",
            a.input.display(),
            info.firmware.why()
        );
    }
    Ok(())
}
