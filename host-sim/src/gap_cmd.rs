//! `host-sim gap` and `host-sim gap-bench`: the sim-to-real gap diagnosis and its benchmark
//! on simulated records with a withheld effect (see `docs/gap.md`).

use crate::gap::{self, bench, effects::Effect};
use crate::gyro::Gyro;
use crate::record_args::RecordArgs;
use anyhow::{Context, Result};
use std::path::PathBuf;

/// `host-sim gap`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The real record: CSV or .csv.gz with `t_s`, the rate column, optional `temp_c`.
    #[arg(long, alias = "real")]
    pub input: PathBuf,
    /// The gyro: a built-in's name or a gyro file (host_sim::gyro), simulated as the
    /// record's model; without it the baseline is ARW + bias instability + rate random walk
    /// fitted to the record's fit blocks.
    #[arg(long, alias = "sim", value_name = "NAME|FILE")]
    pub gyro: Option<String>,
    /// JSON report to write (default: on stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Report folder (index.html, adev.svg, psd.svg).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Also write the model the last round simulated as a gyro file (the baseline or
    /// `--gyro`'s model with the named effects that enter the model; `simulate --gyro`
    /// takes it).
    #[arg(long, alias = "save-model", value_name = "FILE")]
    pub save_gyro: Option<PathBuf>,
    /// The rate column and scale, the sample rate of a record without `t_s`.
    #[command(flatten)]
    pub record: RecordArgs,
    /// Reference (true) rate column for `scale_factor` (default: `true_rate_dps` if present).
    #[arg(long)]
    pub reference_column: Option<String>,
    /// Candidate effects, comma-separated (default: all twelve). Naming `temperature` or
    /// `scale_factor` here makes a missing column an error instead of a skip.
    #[arg(long)]
    pub effects: Option<String>,
    /// Simulations of each model (a count: the seeds are drawn from it).
    #[arg(long, alias = "seeds", default_value_t = 12)]
    pub simulations: usize,
    /// Skip the identification-task comparison.
    #[arg(long)]
    pub no_task: bool,
    /// Cap on the rounds: after each named effect, add it to the model (or take it out of
    /// the record), drop it from the vocabulary, and diagnose again, until `none` (the gap
    /// closed, or nothing left lowers it) or this many rounds (`rounds` in the JSON).
    /// `--rounds 1`: the first decision alone.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..=12))]
    pub rounds: u32,
    /// Keep the fitted baseline's white noise white and Gaussian: no shaping by the record's
    /// own colour above the effects' band, no map to its own platykurtic distribution
    /// (docs/gap.md, "Method" step 2; `colour` and `marginal` in the JSON).
    #[arg(long)]
    pub no_colour: bool,
}

/// Runs `gap`.
pub fn run(a: &Args) -> Result<()> {
    let gyro = a.gyro.as_deref().map(Gyro::from_arg).transpose()?;
    let inputs: Vec<&std::path::Path> = std::iter::once(a.input.as_path())
        .chain(gyro.as_ref().and_then(|g| g.path.as_deref()))
        .collect();
    let report_files: Vec<std::path::PathBuf> = a
        .report
        .iter()
        .flat_map(|d| gap::report::FILES.iter().map(move |f| d.join(f)))
        .collect();
    let outputs: Vec<&std::path::Path> = a
        .json
        .as_deref()
        .into_iter()
        .chain(report_files.iter().map(|p| p.as_path()))
        .chain(a.save_gyro.as_deref())
        .collect();
    crate::record::refuse_overwrite_all(&inputs, &outputs)?;
    if let (Some(g), Some(j)) = (&a.save_gyro, &a.json) {
        if g == j {
            anyhow::bail!("{}: --save-gyro and --json name the same file", g.display());
        }
    }
    let model = gyro.as_ref().map(Gyro::sim_model);
    let opts = crate::record::ReadOptions {
        reference_column: a.reference_column.clone(),
        ..a.record.options()
    };
    let (rec, time) = gap::read_rec(&a.input, &opts)?;
    if let Some(why) = gap::not_static(&rec) {
        anyhow::bail!(
            "{}: {why}; gap diagnoses static records, or the residual against a reference rate (--reference-column)",
            rec.name
        );
    }
    let mut o = gap::Options {
        seeds: a.simulations,
        task: !a.no_task,
        colour: if a.no_colour {
            gap::ColourMode::Off
        } else {
            gap::ColourMode::Fit
        },
        ..Default::default()
    };
    if let Some(e) = &a.effects {
        o.effects = Effect::parse_list(e)?;
        o.explicit = true;
    }
    // A record too short for the held-out split is refused before any round starts.
    gap::features::Layout::new(&rec.t_s, rec.dt_s).with_context(|| rec.name.clone())?;
    let seeds = o.seeds;
    let out = gap::rounds::run(&rec, time, model.as_ref(), &o, a.rounds as usize, |k| {
        eprintln!(
            "{}: round {k} of at most {}: diagnosing ({seeds} simulations of the model) ...",
            rec.name, a.rounds
        );
    })?;
    let d = &out.first;
    let mut value = serde_json::to_value(d).context("JSON encoding")?;
    if let Some(obj) = value.as_object_mut() {
        obj.insert(
            "rounds".into(),
            serde_json::to_value(&out.rounds).context("JSON encoding")?,
        );
        obj.insert("rounds_stopped".into(), out.stopped.clone().into());
        obj.insert("final_gap".into(), out.final_gap.into());
        obj.insert("final_null_gap_95".into(), out.final_null_gap_95.into());
        obj.insert(
            "unexplained".into(),
            serde_json::to_value(&out.unexplained).context("JSON encoding")?,
        );
    }
    let text = serde_json::to_string_pretty(&value).context("JSON encoding")?;
    write_json(a.json.as_deref(), &text)?;
    if let Some(p) = &a.save_gyro {
        crate::gyro::fitted::save_gap(p, &a.input, gyro.as_ref(), &out, rec.dt_s)?;
    }
    eprintln!("{}:", rec.name);
    for l in gap::summary::lines(&out) {
        eprintln!("  {l}");
    }
    if let Some(dir) = &a.report {
        let page = gap::report::write(dir, d)?;
        eprintln!("{}: report -> {}", rec.name, page.display());
    }
    Ok(())
}

/// `host-sim gap-bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Records per class (each effect, and none): a count.
    #[arg(long, alias = "per-effect", default_value_t = 8)]
    pub records_per_class: usize,
    /// Simulations of each model in each diagnosis (a count).
    #[arg(long, alias = "seeds", default_value_t = 12)]
    pub simulations: usize,
    /// Record length, s.
    #[arg(long, default_value_t = 1800.0)]
    pub duration_s: f64,
    /// Sample rate, Hz.
    #[arg(long, default_value_t = 100.0)]
    pub rate_hz: f64,
    /// First record seed.
    #[arg(long, default_value_t = 1)]
    pub first_seed: u64,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// Classes to run, comma-separated effect words and `none` (default: all thirteen).
    #[arg(long)]
    pub classes: Option<String>,
    /// Also write every record (CSV: t_s, rate_dps, temp_c, true_rate_dps) and the baseline
    /// model (`baseline.toml`, a gyro file) into this folder, to rerun `gap --gyro` on one.
    #[arg(long, alias = "write-records", value_name = "DIR")]
    pub save_records: Option<PathBuf>,
    /// JSON report to write (the table is on stdout either way).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs `gap-bench`.
pub fn run_bench(a: &BenchArgs) -> Result<()> {
    let mut o = bench::BenchOptions {
        per_effect: a.records_per_class,
        seeds: a.simulations,
        duration_s: a.duration_s,
        rate_hz: a.rate_hz,
        first_seed: a.first_seed,
        jobs: a.jobs,
        ..Default::default()
    };
    if let Some(c) = &a.classes {
        o.classes = Vec::new();
        for w in c.split(',').map(str::trim) {
            if w == "none" {
                o.classes.push(None);
            } else {
                o.classes
                    .extend(Effect::parse_list(w)?.into_iter().map(Some));
            }
        }
    }
    if let Some(dir) = &a.save_records {
        write_records(dir, &o)?;
    }
    let r = bench::run(&o, &|r| {
        eprintln!(
            "{:>18} -> {:<18} gap {:8.2} shrink(true) {:>6}",
            r.truth,
            r.diagnosed,
            r.gap_before,
            r.shrink_true_effect
                .map_or("-".to_string(), |s| format!("{s:.2}"))
        );
    })?;
    if let Some(j) = &a.json {
        let text = serde_json::to_string_pretty(&r).context("JSON encoding")?;
        write_json(Some(j), &text)?;
    }
    print!("{}", bench::table(&r));
    Ok(())
}

/// Writes `text` to `path` (atomically), or on stdout without a path.
fn write_json(path: Option<&std::path::Path>, text: &str) -> Result<()> {
    use std::io::Write;
    match path {
        Some(p) => crate::record::write_atomic(p, |w| {
            w.write_all(text.as_bytes())
                .with_context(|| format!("{}: write failed", p.display()))
        }),
        None => {
            let mut out = std::io::stdout().lock();
            writeln!(out, "{text}").context("stdout: write failed")
        }
    }
}

/// Writes the benchmark's records and baseline model into `dir`.
fn write_records(dir: &std::path::Path, o: &bench::BenchOptions) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let parts = crate::gyro::write::Parts {
        header: vec!["gap-bench's baseline model (a gyro file: gap --gyro baseline.toml)".into()],
        name: "baseline",
        model: bench::baseline_model(o.rate_hz),
        ..Default::default()
    };
    crate::gyro::write::save(&dir.join("baseline.toml"), &parts, &[])?;
    for (ci, c) in o.classes.iter().enumerate() {
        for k in 0..o.per_effect {
            let seed = o.first_seed + (ci * 1000 + k) as u64;
            let (rec, _, _) = bench::make_record(*c, seed, o.duration_s, o.rate_hz)?;
            let p = dir.join(format!("{}_{seed}.csv", c.map_or("none", Effect::name)));
            crate::record::write_atomic(&p, |w| {
                use std::io::Write;
                let e = |e: std::io::Error| anyhow::anyhow!("{}: {e}", p.display());
                writeln!(w, "t_s,rate_dps,temp_c,true_rate_dps").map_err(e)?;
                for i in 0..rec.t_s.len() {
                    writeln!(
                        w,
                        "{},{},{},{}",
                        rec.t_s[i],
                        rec.rate_dps[i],
                        rec.temp_c.as_ref().map_or(0.0, |v| v[i]),
                        rec.ref_dps.as_ref().map_or(0.0, |v| v[i])
                    )
                    .map_err(e)?;
                }
                Ok(())
            })?;
        }
    }
    Ok(())
}
