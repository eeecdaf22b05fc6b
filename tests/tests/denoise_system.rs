//! System tests across crates for the denoiser: host-sim drives exactly fog-core's code, and
//! real recordings (when `../shared/data/real` is present) go through without loss.

use assert_cmd::assert::OutputAssertExt;
use fog_core::{BlockDenoiser, DenoiseConfig, Push};
use fog_system_tests::{host_sim, shared_real};
use std::fs;
use std::path::Path;

fn lcg_record(n: usize) -> (String, Vec<f32>) {
    let mut s = String::from("t_s,rate_dps\n");
    let mut rates = Vec::with_capacity(n);
    let mut state = 2024u32;
    for i in 0..n {
        state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        // Quantized like an E-Core 2000 at 60 deg/s full scale.
        let counts = ((state >> 16) as i32 % 41) - 20 + 27;
        let r = counts as f32 * (60.0 / 32768.0);
        rates.push(r);
        s.push_str(&format!("{:.2},{}\n", i as f64 * 0.01, r));
    }
    (s, rates)
}

fn denoised_column(path: &Path) -> Vec<f32> {
    let mut rdr = csv::Reader::from_path(path).expect("output readable");
    let col = rdr
        .headers()
        .expect("header")
        .iter()
        .position(|h| h == "denoised_dps")
        .expect("column present");
    rdr.records()
        .map(|r| r.expect("row")[col].parse::<f32>().expect("number"))
        .collect()
}

/// host-sim denoise, cut in 512-sample blocks, gives bit for bit what the firmware's
/// `BlockDenoiser<512>` gives sample by sample.
#[test]
fn host_sim_denoise_equals_fog_core_block_denoiser_bit_for_bit() {
    let dir = tempfile::tempdir().expect("tmp");
    let (csv_text, rates) = lcg_record(2048);
    let input = dir.path().join("rec.csv");
    fs::write(&input, csv_text).expect("write");
    let output = dir.path().join("out.csv");
    host_sim()
        .args(["denoise", "--block", "512", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&output)
        .assert()
        .success();
    let host = denoised_column(&output);
    let mut bd = BlockDenoiser::<512>::new(DenoiseConfig::PAPER).expect("config");
    let mut core = Vec::new();
    for &r in &rates {
        if let Push::Block(b, _) = bd.push(r).expect("finite") {
            core.extend_from_slice(b);
        }
    }
    assert_eq!(host.len(), core.len());
    let mismatches = host
        .iter()
        .zip(&core)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert_eq!(
        mismatches, 0,
        "host-sim and fog-core differ in {mismatches} samples"
    );
}

/// A real static MEMS record (ADIS16405, Calgary; CC BY-NC-SA, read in place, never
/// copied): the z gyro's first 100,000 samples become an interchange CSV; every row comes
/// back, and denoising lowers the sample-to-sample scatter.
#[test]
fn real_adis16405_record_goes_through_without_loss() {
    let Some(real) = shared_real() else { return };
    let src = real.join("adis16405_calgary/adis16405_run1_gyro.csv");
    let mut rdr = csv::Reader::from_path(&src).expect("real record readable");
    let gz = rdr
        .headers()
        .expect("h")
        .iter()
        .position(|h| h == "gz_dps")
        .expect("gz_dps column");
    let mut text = String::from("t_s,rate_dps\n");
    let mut rates = Vec::new();
    for rec in rdr.records().take(100_000) {
        let rec = rec.expect("row");
        let r: f64 = rec[gz].parse().expect("number");
        text.push_str(&format!("{},{}\n", &rec[0], r));
        rates.push(r);
    }
    let dir = tempfile::tempdir().expect("tmp");
    let input = dir.path().join("adis_gz.csv");
    fs::write(&input, text).expect("write");
    let output = dir.path().join("out.csv");
    host_sim()
        .args(["denoise", "--input"])
        .arg(&input)
        .arg("--output")
        .arg(&output)
        .assert()
        .success();
    let den = denoised_column(&output);
    assert_eq!(den.len(), rates.len(), "every row comes back");
    let scatter = |v: &[f64]| {
        (v.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    let den64: Vec<f64> = den.iter().map(|&v| f64::from(v)).collect();
    let (before, after) = (scatter(&rates), scatter(&den64));
    eprintln!("ADIS16405 gz: sample-to-sample scatter {before:.5} -> {after:.5} deg/s");
    assert!(after < 0.5 * before, "{after} vs {before}");
    // The mean (bias) is kept: denoising removes noise, not the signal's level.
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!((mean(&rates) - mean(&den64)).abs() < 1e-4);
}
