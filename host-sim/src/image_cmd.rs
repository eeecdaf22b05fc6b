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
/// stderr ([`crate::firmware_fit`]), both in the JSON. An image the firmware would refuse
/// at set-up: the same lines, then an error naming the image (non-zero exit) and no JSON.
pub fn run(a: &Args) -> Result<()> {
    let bytes =
        std::fs::read(&a.input).with_context(|| format!("{}: cannot read", a.input.display()))?;
    let image = Image::parse(&bytes).map_err(|e| anyhow!("{}: {e}", a.input.display()))?;
    let info = show::describe(&image, &bytes);
    print!("{}", show::text(&a.input.display().to_string(), &info));
    eprint!("{}", info.firmware.text());
    if let Some(r) = &info.firmware.refusal {
        bail!(
            "{}: the firmware would refuse this image at set-up: {r}",
            a.input.display()
        );
    }
    if let Some(j) = &a.json {
        record::refuse_overwrite(&a.input, j)?;
        let text = serde_json::to_string_pretty(&info)?;
        record::write_atomic(j, |w| {
            std::io::Write::write_all(w, text.as_bytes())
                .with_context(|| format!("{}: write failed", j.display()))
        })?;
    }
    Ok(())
}
