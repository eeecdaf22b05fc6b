//! `host-sim gap`: the fitted baseline reproduces the record's own platykurtic value
//! distribution (issue 43: the ADIS16405 z axes' near-constant-amplitude oscillation at
//! 19.7 Hz, excess kurtosis -0.27), and keeps a Gaussian record's white term Gaussian.

mod common;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

/// Writes `n` samples at 100 Hz: white noise of sd 0.3 deg/s plus, when `tone`, an
/// oscillation of constant amplitude near 19.7 Hz whose phase diffuses (0.3 rad per sample:
/// a band about 3 Hz wide, as the ADIS16405's), carrying 0.42 of the variance (excess
/// kurtosis about -0.27).
fn write_record(p: &Path, n: usize, seed: u64, tone: bool) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let share: f64 = if tone { 0.424 } else { 0.0 };
    let amp = (2.0 * share * 0.09 / (1.0 - share)).sqrt();
    let mut phase = 0.0f64;
    let mut f = std::io::BufWriter::new(std::fs::File::create(p).expect("create"));
    writeln!(f, "t_s,rate_dps").expect("write");
    for i in 0..n {
        let (e, d): (f64, f64) = (
            StandardNormal.sample(&mut rng),
            StandardNormal.sample(&mut rng),
        );
        phase += std::f64::consts::TAU * 19.7 * 0.01 + 0.3 * d;
        writeln!(f, "{},{}", i as f64 * 0.01, 0.3 * e + amp * phase.sin()).expect("write");
    }
}

/// One round of `gap` on `p` (extra `args`): the JSON and stderr.
fn gap(p: &Path, json: &Path, args: &[&str]) -> (serde_json::Value, String) {
    let mut all = vec!["--simulations", "6", "--no-task", "--rounds", "1"];
    all.extend(["--effects", "white_noise"]);
    all.extend_from_slice(args);
    common::gap(p, json, &all)
}

/// The held-out `dist` group's gap and its largest null.
fn dist_gap(v: &serde_json::Value) -> (f64, f64) {
    let g = v["group_gap_before"]["dist"].as_f64().expect("dist gap");
    let nulls: Vec<f64> = v["null_group_gaps"]["dist"]
        .as_array()
        .expect("dist nulls")
        .iter()
        .filter_map(|x| x.as_f64())
        .collect();
    (g, nulls.iter().copied().fold(0.0, f64::max))
}

/// A platykurtic record: the baseline's white term gets the record's distribution (rho
/// near the oscillation's share, said on stderr) and the held-out `dist` gap is within
/// twice the largest null's (floored at 1); without it (`--no-colour`, the Gaussian white
/// term of before) the `dist` gap is more than 8 times the largest null (floored at 1).
#[test]
fn a_platykurtic_record_s_distribution_is_reproduced() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("platy.csv");
    write_record(&p, 30_000, 5, true);
    let (v, err) = gap(&p, &dir.path().join("marginal.json"), &[]);
    let m = &v["marginal"];
    assert!(m.is_object(), "no marginal fitted: {}", v["marginal_fit"]);
    let rho = m["rho"].as_f64().expect("rho");
    assert!((rho - 0.424).abs() < 0.1, "rho {rho}");
    let k = m["excess_kurtosis"].as_f64().expect("kurtosis");
    assert!((k + 0.27).abs() < 0.08, "record's excess kurtosis {k}");
    assert!(
        err.contains("the model's white noise has the record's own platykurtic distribution"),
        "{err}"
    );
    let (with, null_with) = dist_gap(&v);
    assert!(
        with < 2.0 * null_with.max(1.0),
        "dist gap {with} (null {null_with})"
    );
    let (v0, err0) = gap(&p, &dir.path().join("gaussian.json"), &["--no-colour"]);
    assert!(v0["marginal"].is_null() && v0["marginal_fit"].is_null());
    assert!(!err0.contains("platykurtic"), "{err0}");
    let (without, null_without) = dist_gap(&v0);
    eprintln!(
        "dist gap {with} (null {null_with}); without the marginal {without} (null {null_without})"
    );
    assert!(
        without > 8.0 * null_without.max(1.0),
        "dist gap without the marginal {without} (null {null_without})"
    );
}

/// A Gaussian record keeps a Gaussian white term: the gate does not pass.
#[test]
fn a_gaussian_record_stays_gaussian() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("gauss.csv");
    write_record(&p, 30_000, 6, false);
    let (v, err) = gap(&p, &dir.path().join("o.json"), &[]);
    assert!(v["marginal"].is_null(), "{}", v["marginal"]);
    let f = &v["marginal_fit"];
    let gate = f["gate_sds"].as_f64().expect("gate");
    assert!(gate < 5.0, "gate {gate}");
    assert!(!err.contains("platykurtic distribution"), "{err}");
}

/// A record's rate and its fit blocks' sample ranges.
type Blocks = (Vec<f64>, Vec<(usize, usize)>);

/// The first 600 s after sample 20,000 of ADIS16405 run 4 (real, `../shared/data/real`),
/// column `col`, and its fit blocks (0, 2, 4 of 6); None when the record is absent.
fn adis_run4(col: &str) -> Option<Blocks> {
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/adis16405_calgary/adis16405_run4.csv.gz");
    if !src.exists() {
        eprintln!("skipped: {} absent", src.display());
        return None;
    }
    let r = std::io::BufReader::new(flate2::read::GzDecoder::new(
        std::fs::File::open(&src).expect("open"),
    ));
    let mut lines = r.lines();
    let head = lines.next().expect("header").expect("line");
    let c = head.split(',').position(|h| h == col).expect("column");
    let y: Vec<f64> = lines
        .skip(20_000)
        .take(60_000)
        .map(|l| {
            let l = l.expect("line");
            l.split(',').nth(c).expect("field").parse().expect("number")
        })
        .collect();
    let n = y.len();
    let ranges = (0..6)
        .step_by(2)
        .map(|b| (n * b / 6, n * (b + 1) / 6))
        .collect();
    Some((y, ranges))
}

/// Real ADIS16405 run 4: the z axis (its 19.7-Hz oscillation) passes the gate with rho
/// near 0.43; the x axis (excess kurtosis within its noise) does not.
#[test]
fn real_adis_z_is_platykurtic_and_x_is_not() {
    use host_sim::gap::marginal::Marginal;
    let var = |y: &[f64]| {
        let m = y.iter().sum::<f64>() / y.len() as f64;
        y.iter().map(|x| (x - m).powi(2)).sum::<f64>() / y.len() as f64
    };
    let Some((z, r)) = adis_run4("gz_dps") else {
        return;
    };
    let f = Marginal::fit(&z, &z, &r, var(&z));
    let m = f.marginal.clone().expect("run 4 z passes the gate");
    assert!(f.excess_kurtosis < -0.2 && f.gate_sds > 5.0, "{f:?}");
    assert!((f.quantum_of_sd - 0.12).abs() < 0.03, "{f:?}");
    assert!((m.rho - 0.43).abs() < 0.08, "rho {}", m.rho);
    let Some((x, r)) = adis_run4("gx_dps") else {
        return;
    };
    let f = Marginal::fit(&x, &x, &r, var(&x));
    assert!(f.marginal.is_none(), "{f:?}");
}
