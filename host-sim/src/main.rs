//! `host-sim`: the bench tool that drives the same fog-core code as the firmware on recorded
//! or simulated gyro data.
#![forbid(unsafe_code)]

use clap::{Parser, Subcommand};
use host_sim::{
    allan_cmd, demo_cmd, denoise_cmd, gap_cmd, gyro_cmd, identify_cmd, image_cmd, replay_cmd,
    reproduce_cmd, simulate_cmd,
};
use std::process::ExitCode;

/// FOG drift identification on the bench: the firmware's pipeline on recorded or simulated data.
#[derive(Parser, Debug)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Wavelet-denoise a recording: adds a `denoised_dps` column (db4 lifting, soft universal
    /// threshold, as in the paper).
    Denoise(denoise_cmd::Args),
    /// Simulate a FOG record from a gyro file or a built-in gyro (`--gyro`): interchange
    /// CSV or E-Core binary frames, streamed sample by sample.
    Simulate(simulate_cmd::Args),
    /// Overlapping Allan deviation of a static record with chi-square error bars and a
    /// weighted NNLS fit of the IEEE 952 noise terms; summary on stdout, optional JSON and
    /// SVG plot.
    Allan(allan_cmd::Args),
    /// Train the on-line drift identifier on training records and score it, still on line,
    /// on validation records beside causal baselines; JSON report.
    Identify(identify_cmd::Args),
    /// What an image (`.fogi`) holds: format, checksum, the gyro model fitted on the
    /// calibration runs, the drift filter's settings, and what the firmware does with it.
    Image(image_cmd::Args),
    /// The paper's section 5 on simulated records: 265 records of 1800 s (180 train, 85
    /// validate) at different seeds, sample periods and conditions; JSON report.
    Reproduce(reproduce_cmd::Args),
    /// Replay a recording (interchange CSV, E-Core binary capture or DSP-3000 lines) through
    /// the firmware's pipeline, streamed: per-sample CSV and an optional report folder.
    Replay(replay_cmd::Args),
    /// The main job with no configuration: fit the gyro model on 12 simulated static E-Core
    /// records, tune it on 32 simulated vehicles, replay another vehicle
    /// record (CSV) and score it and 32 test vehicles beside the causal baselines; report
    /// folder (index.html, SVG figures, summary.json).
    Demo(demo_cmd::Args),
    /// Sim-to-real gap: where a real record departs from its model's simulations, which
    /// effect the model lacks, and how much of the gap closes on held-out data.
    Gap(gap_cmd::Args),
    /// Benchmark of `gap` on simulated records with one withheld effect: confusion matrix.
    GapBench(gap_cmd::BenchArgs),
    /// The gyro file (one TOML file per gyro, read by `--gyro` everywhere): convert an old
    /// sensor or model file, show a built-in.
    Gyro(gyro_cmd::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Ctrl-C, SIGTERM and SIGHUP (the `ctrlc` crate): no temporary output file survives.
    if let Err(e) = ctrlc::set_handler(|| {
        let n = host_sim::record::remove_live_temp_files();
        eprintln!("interrupted: {n} temporary output file(s) removed; no partial output left");
        std::process::exit(130);
    }) {
        eprintln!("warning: cannot install the Ctrl-C / SIGTERM handler: {e}");
    }
    let result = match &cli.cmd {
        Cmd::Denoise(a) => denoise_cmd::run(a),
        Cmd::Simulate(a) => simulate_cmd::run(a),
        Cmd::Allan(a) => allan_cmd::run(a),
        Cmd::Identify(a) => identify_cmd::run(a),
        Cmd::Image(a) => image_cmd::run(a),
        Cmd::Reproduce(a) => reproduce_cmd::run(a),
        Cmd::Replay(a) => replay_cmd::run(a),
        Cmd::Demo(a) => demo_cmd::run(a),
        Cmd::Gap(a) => gap_cmd::run(a),
        Cmd::GapBench(a) => gap_cmd::run_bench(a),
        Cmd::Gyro(a) => gyro_cmd::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the context chain joined, most specific last.
            eprintln!("error: {}", format!("{e:#}").replace('\n', " "));
            ExitCode::FAILURE
        }
    }
}
