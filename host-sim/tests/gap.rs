//! `host-sim gap` and `gap-bench`: a CI-sized benchmark that can fail, the robustness
//! messages, and a run on a real recording (skipped when /work/shared is absent).

use assert_cmd::Command;
use host_sim::gap::{self, bench, effects::Effect};
use host_sim::record::ReadOptions;
use std::io::Write;
use std::path::PathBuf;

fn write_csv(path: &std::path::Path, rows: impl Iterator<Item = String>, header: &str) {
    let mut f = std::fs::File::create(path).expect("create csv");
    writeln!(f, "{header}").expect("write");
    for r in rows {
        writeln!(f, "{r}").expect("write");
    }
}

/// Reduced benchmark: 600 s at 25 Hz, 6 simulations, one record for each of the classes
/// the diagnosis must get right even at this size. Fails if fewer than 6 of 7 are named
/// right.
#[test]
fn ci_bench_names_withheld_effects() {
    let o = bench::BenchOptions {
        per_effect: 1,
        seeds: 6,
        duration_s: 600.0,
        rate_hz: 25.0,
        first_seed: 7,
        jobs: 2,
        classes: vec![
            None,
            Some(Effect::WhiteNoise),
            Some(Effect::BiasInstability),
            Some(Effect::Sinusoid),
            Some(Effect::Spikes),
            Some(Effect::Dropouts),
            Some(Effect::ScaleFactor),
        ],
    };
    let r = bench::run(&o, &|_| {}).expect("bench runs");
    print!("{}", bench::table(&r));
    let right = r.records.iter().filter(|x| x.truth == x.diagnosed).count();
    assert!(
        right >= 6,
        "only {right} of {} named right",
        r.records.len()
    );
    for x in r.records.iter().filter(|x| x.truth != "none") {
        assert!(
            x.shrink_true_effect.unwrap_or(0.0) > 0.5,
            "{}: shrink {:?}",
            x.truth,
            x.shrink_true_effect
        );
    }
}

/// `host-sim gap --real p --json dir/o.json`, which must fail with one line on stderr and
/// write no JSON; returns that line.
/// Runs `host-sim gap ARGS --real REAL --json JSON`, which must succeed, and parses the JSON.
fn gap_json(real: &std::path::Path, json: &std::path::Path, args: &[&str]) -> serde_json::Value {
    Command::cargo_bin("host-sim")
        .expect("binary")
        .arg("gap")
        .args(args)
        .arg("--input")
        .arg(real)
        .arg("--json")
        .arg(json)
        .assert()
        .success();
    serde_json::from_str(&std::fs::read_to_string(json).expect("json")).expect("parse")
}

fn gap_refused(p: &std::path::Path, dir: &std::path::Path) -> String {
    let json = dir.join("o.json");
    let out = Command::cargo_bin("host-sim")
        .expect("binary")
        .args(["gap", "--input"])
        .arg(p)
        .args(["--json"])
        .arg(&json)
        .assert()
        .failure();
    let err = String::from_utf8_lossy(&out.get_output().stderr).to_string();
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!json.exists());
    err
}

#[test]
fn too_short_record_says_how_long_is_needed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("short.csv");
    write_csv(
        &p,
        (0..1000).map(|i| format!("{},{}", i as f64 * 0.01, 0.001 * ((i * 7919) % 13) as f64)),
        "t_s,rate_dps",
    );
    let err = gap_refused(&p, dir.path());
    assert!(
        err.contains("too short") && err.contains("12288 samples"),
        "{err}"
    );
}

#[test]
fn explicit_temperature_without_temp_c_is_an_error() {
    let (rec, time, _) = bench::make_record(None, 3, 600.0, 25.0).expect("record");
    let mut rec = rec;
    rec.temp_c = None;
    let o = gap::Options {
        seeds: 4,
        effects: vec![Effect::Temperature],
        explicit: true,
        task: false,
        ..Default::default()
    };
    let e = gap::diagnose(&rec, time.clone(), Some(&bench::baseline_model(25.0)), &o)
        .expect_err("must refuse");
    assert!(format!("{e:#}").contains("temp_c"), "{e:#}");
    // Not asked for explicitly: skipped with a reason.
    let o = gap::Options {
        seeds: 4,
        effects: vec![Effect::Temperature, Effect::WhiteNoise],
        task: false,
        ..Default::default()
    };
    let d = gap::diagnose(&rec, time, Some(&bench::baseline_model(25.0)), &o).expect("runs");
    let t = &d.candidates[0];
    assert!(t.skipped.as_deref().unwrap_or("").contains("temp_c"));
}

#[test]
fn cli_writes_json_with_gaps_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (rec, _, _) = bench::make_record(Some(Effect::Dropouts), 11, 600.0, 25.0).expect("rec");
    let p = dir.path().join("rec.csv");
    // With its turntable reference (the record turns: without it, not static).
    write_csv(
        &p,
        (0..rec.t_s.len()).map(|i| {
            format!(
                "{},{},{},{}",
                rec.t_s[i],
                rec.rate_dps[i],
                rec.temp_c.as_ref().map_or(0.0, |v| v[i]),
                rec.ref_dps.as_ref().map_or(0.0, |v| v[i])
            )
        }),
        "t_s,rate_dps,temp_c,true_rate_dps",
    );
    let json = dir.path().join("gap.json");
    let report = dir.path().join("rep");
    Command::cargo_bin("host-sim")
        .expect("binary")
        .args([
            "gap",
            "--simulations",
            "4",
            "--no-task",
            "--rounds",
            "1",
            "--input",
        ])
        .arg(&p)
        .arg("--json")
        .arg(&json)
        .arg("--report")
        .arg(&report)
        .assert()
        .success();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("json")).expect("parse");
    for k in [
        "effect",
        "gap_before",
        "gap_after",
        "shrink",
        "where",
        "candidates",
    ] {
        assert!(v.get(k).is_some(), "missing key {k}");
    }
    assert!(v["time"]["gap_count"].as_u64().unwrap_or(0) > 0);
    let sf = v["candidates"]
        .as_array()
        .expect("array")
        .iter()
        .find(|c| c["effect"] == "scale_factor")
        .expect("scale_factor listed");
    // With the reference the scale factor is measurable (without it the record is refused as
    // not static).
    assert!(!sf["skipped"]
        .as_str()
        .unwrap_or("")
        .contains("not applicable"));
    assert!(report.join("index.html").exists() && report.join("adev.svg").exists());
}

/// `gap --rounds`: a record with two effects (a strong ramp on a quantized rate) gets both
/// named, one per round, quantization first, then `none` (within the cap, no effect twice);
/// the ramp's 95 % interval holds the true slope; the rounds say why they stopped and what
/// stays unexplained (nothing here: one more draw of the model).
#[test]
fn rounds_name_two_effects_in_turn() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("two.csv");
    let (dt, n, q, slope) = (0.05, 24_000, 0.004, 8e-6);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(21);
    write_csv(
        &p,
        (0..n).map(|i| {
            let t = i as f64 * dt;
            let e: f64 = StandardNormal.sample(&mut rng);
            let v = 0.01 * e + slope * t;
            format!("{t},{}", (v / q).round() * q)
        }),
        "t_s,rate_dps",
    );
    let saved = dir.path().join("saved.toml");
    let v = gap_json(
        &p,
        &dir.path().join("rounds.json"),
        &[
            "--simulations",
            "6",
            "--no-task",
            "--rounds",
            "3",
            "--save-gyro",
            saved.to_str().expect("path"),
        ],
    );
    let rounds = v["rounds"].as_array().expect("rounds");
    let named: Vec<&str> = rounds.iter().filter_map(|r| r["effect"].as_str()).collect();
    assert_eq!(
        named,
        ["quantization", "rate_ramp", "none"],
        "rounds named {named:?}"
    );
    let stopped = v["rounds_stopped"].as_str().expect("rounds_stopped");
    assert!(stopped.contains("round 3 named none"), "{stopped}");
    let unexplained = v["unexplained"].as_array().expect("unexplained");
    assert!(
        v["final_gap"].as_f64().expect("final_gap")
            <= v["final_null_gap_95"].as_f64().expect("final_null_gap_95")
            || !unexplained.is_empty(),
        "a gap above the null's 95 % names its groups"
    );
    let ramp = rounds
        .iter()
        .find(|r| r["effect"] == "rate_ramp")
        .expect("ramp round");
    let ci = &ramp["params_ci95"]["rate_ramp_dps_per_s"];
    let (lo, hi) = (ci[0].as_f64().expect("lo"), ci[1].as_f64().expect("hi"));
    assert!(
        lo < slope && slope < hi,
        "slope {slope} outside [{lo}, {hi}]"
    );
    // The ramp left the record in the rounds: the slope of its least-squares line over all
    // samples (nothing else was taken out before it); the saved model holds that slope.
    let applied = ramp["applied"].as_str().expect("applied");
    assert!(applied.starts_with("subtracted a rate ramp"), "{applied}");
    let text = std::fs::read_to_string(&p).expect("record");
    let (t, y): (Vec<f64>, Vec<f64>) = text
        .lines()
        .skip(1)
        .filter_map(|l| {
            let (a, b) = l.split_once(',')?;
            Some((a.parse::<f64>().ok()?, b.parse::<f64>().ok()?))
        })
        .unzip();
    assert_eq!(t.len(), n);
    let (mt, my) = (
        t.iter().sum::<f64>() / n as f64,
        y.iter().sum::<f64>() / n as f64,
    );
    let sxy: f64 = t.iter().zip(&y).map(|(a, b)| (a - mt) * (b - my)).sum();
    let sxx: f64 = t.iter().map(|a| (a - mt) * (a - mt)).sum();
    let ols = sxy / sxx;
    let g = host_sim::gyro::Gyro::load(&saved).expect("saved gyro");
    let kept = g.model.noise.rate_ramp_dps_per_s;
    assert!((kept - ols).abs() <= 1e-6 * ols.abs(), "{kept} vs {ols}");
    assert!(lo < kept && kept < hi, "saved {kept} outside [{lo}, {hi}]");
}

/// The MPU-6050 10-minute static record (bursty stamps, temp_c): runs and names something
/// or `none`, with a finite held-out gap.
#[test]
fn real_mpu6050_runs() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/mpu6050_sunsided/unmoved-with-x-pointing-forward-10min.csv");
    if !p.is_file() {
        eprintln!(
            "SKIPPED: {} is absent (it exists in CI, not in a user's clone)",
            p.display()
        );
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let v = gap_json(
        &p,
        &dir.path().join("mpu.json"),
        &[
            "--simulations",
            "4",
            "--no-task",
            "--rounds",
            "1",
            "--rate-column",
            "gz_dps",
            "--effects",
            "white_noise,bias_instability,temperature,warmup,rate_ramp",
        ],
    );
    assert!(v["gap_before"].as_f64().is_some_and(f64::is_finite));
    assert_eq!(v["time"]["bursty"], true);
}

/// The drift variograms the markov / rate_random_walk fits use: at lag = window they are
/// twice the Allan variance (adjacent windows), and a Gauss-Markov term with T far above
/// the lags is a rate random walk with K^2 = 2 sigma^2 / T (the nested limit that makes
/// `markov` collapse to `rate_random_walk`).
#[test]
fn drift_variograms_match_allan_and_the_nested_limit() {
    use host_sim::gap::effects::{gm_variogram, rrw_variogram};
    use host_sim::sim::gm_avar;
    let w = 37.5;
    assert!((rrw_variogram(w, w) - 2.0 * w / 3.0).abs() < 1e-12);
    for t in [2.0, 40.0, 900.0] {
        let v = gm_variogram(t, w, w);
        let a = 2.0 * gm_avar(1.0, t, w);
        assert!((v - a).abs() < 1e-6 * a, "T {t}: {v} vs {a}");
    }
    // T = 1e6 s, sigma^2 = T / 2 (K = 1): within 1 % of L - W/3 up to L = 1500 s.
    for l in [75.0, 600.0, 1500.0] {
        let g = 0.5e6 * gm_variogram(1e6, l, w);
        let r = rrw_variogram(l, w);
        assert!((g / r - 1.0).abs() < 0.01, "lag {l}: {g} vs {r}");
    }
    // Bounded: a short-T variogram is flat (2 Var(window mean)) beyond a few T.
    let (a, b) = (gm_variogram(10.0, 300.0, w), gm_variogram(10.0, 1200.0, w));
    assert!((a / b - 1.0).abs() < 1e-6, "{a} vs {b}");
}

/// 1800 s at 10 Hz of white noise (N) and a rate random walk (K), deg/s, seeded.
fn white_and_walk(seed: u64, n_dps: f64, k_dps: f64) -> (Vec<f64>, Vec<f64>) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let (dt, n) = (0.1, 18_000);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut walk = 0.0;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let y = (0..n)
        .map(|_| {
            let (a, b): (f64, f64) = (
                StandardNormal.sample(&mut rng),
                StandardNormal.sample(&mut rng),
            );
            walk += k_dps * dt.sqrt() * a;
            walk + n_dps / dt.sqrt() * b
        })
        .collect();
    (t, y)
}

fn drift_run(t: &[f64], y: &[f64], temp: Option<&[f64]>) -> host_sim::gap::drift::DriftTests {
    use host_sim::gap::drift::{DriftTests, Windows};
    DriftTests::run(&Windows::new(t, y, temp, 1800.0), 1).expect("drift fit")
}

fn passed(d: &host_sim::gap::drift::DriftTests) -> Vec<host_sim::gap::effects::Effect> {
    d.outcomes()
        .iter()
        .filter(|t| t.passed)
        .map(|t| t.effect)
        .collect()
}

/// White noise and a random walk: the drift tests' null fit finds N and K, no ramp; with a
/// ramp of 20 times the walk's own change per record, the ramp is found and its slope lies
/// within 3 standard errors.
#[test]
fn drift_null_fits_the_noise_and_finds_a_ramp() {
    use host_sim::gap::effects::Effect;
    let (nn, kk) = (0.01, 2e-4);
    let (t, y) = white_and_walk(5, nn, kk);
    let r = drift_run(&t, &y, None);
    assert!(
        (r.null.arw_dps_per_rthz / nn - 1.0).abs() < 0.25,
        "{:?}",
        r.null
    );
    assert!(
        (r.null.rrw_dps_per_s_rthz / kk - 1.0).abs() < 0.5,
        "{:?}",
        r.null
    );
    let ramp_of = |d: &host_sim::gap::drift::DriftTests| {
        d.models
            .iter()
            .find(|m| m.effect == Effect::RateRamp)
            .cloned()
            .expect("ramp")
    };
    let ramp = ramp_of(&r);
    assert!(ramp.p_value > 0.001, "no ramp: p {}", ramp.p_value);
    let slope = 20.0 * kk * 1800f64.sqrt() / 1800.0;
    let y2: Vec<f64> = y.iter().zip(&t).map(|(v, t)| v + slope * t).collect();
    let ramp = ramp_of(&drift_run(&t, &y2, None));
    assert!(ramp.p_value < 1e-4, "ramp p {}", ramp.p_value);
    let (b, se) = (ramp.fit.beta[0], ramp.fit.beta_se[0]);
    assert!(
        (b - slope).abs() < 3.0 * se,
        "slope {b} +- {se}, true {slope}"
    );
}

/// The drift likelihood tests (issue 26): a ramp, a warm-up and a drift that follows the
/// temperature channel are each named over a random walk; the same drift against a channel
/// that does not drive it is not taken for temperature; and on records without a drift the
/// ramp test's p-values are not too small (20 records: at most 4 below 0.05, 1 expected).
#[test]
fn drift_tests_name_ramp_warmup_and_temperature_over_a_walk() {
    use host_sim::gap::effects::Effect;
    let (nn, kk) = (0.01, 1e-4);
    let (t, base) = white_and_walk(3, nn, kk);
    // Ramp: 10 sigma of the walk's own change over the record.
    let slope = 10.0 * kk * 1800f64.sqrt() / 1800.0;
    let ramp: Vec<f64> = base.iter().zip(&t).map(|(v, t)| v + slope * t).collect();
    let d = drift_run(&t, &ramp, None);
    assert_eq!(
        d.pick(&d.outcomes()),
        Some(Effect::RateRamp),
        "{:?}",
        d.models
    );
    let warm: Vec<f64> = base
        .iter()
        .zip(&t)
        .map(|(v, t)| v + 0.02 * (-t / 150.0).exp())
        .collect();
    let d = drift_run(&t, &warm, None);
    assert_eq!(
        d.pick(&d.outcomes()),
        Some(Effect::Warmup),
        "{:?}",
        d.models
    );
    let tau = d
        .models
        .iter()
        .find(|m| m.effect == Effect::Warmup)
        .and_then(|m| m.tau_s);
    assert!(
        tau.is_some_and(|x| (75.0..=300.0).contains(&x)),
        "tau {tau:?} (truth 150 s)"
    );
    // Temperature: a warm-up rise and a cycle; the drift follows it.
    let temp: Vec<f64> = t
        .iter()
        .map(|&t| 25.0 + 5.0 * (1.0 - (-t / 400.0).exp()) + (t / 150.0).sin())
        .collect();
    let other: Vec<f64> = t.iter().map(|&t| 25.0 + (t / 230.0 + 1.0).cos()).collect();
    let driven: Vec<f64> = base
        .iter()
        .zip(&temp)
        .map(|(v, c)| v + 0.004 * (c - 25.0))
        .collect();
    let d = drift_run(&t, &driven, Some(&temp));
    assert_eq!(
        d.pick(&d.outcomes()),
        Some(Effect::Temperature),
        "{:?}",
        d.models
    );
    let (p, ci) = d.params(Effect::Temperature).expect("params");
    let c = ci["bias_dps_per_c"];
    assert!(
        c[0] < 0.004 && 0.004 < c[1],
        "coefficient {} in {c:?}",
        p["bias_dps_per_c"]
    );
    let d = drift_run(&t, &base, Some(&other));
    assert!(!passed(&d).contains(&Effect::Temperature), "{:?}", d.models);
    let low = (0..20)
        .filter(|&s| {
            let (t, y) = white_and_walk(100 + s, nn, kk);
            let d = drift_run(&t, &y, None);
            d.models
                .iter()
                .any(|m| m.effect == Effect::RateRamp && m.p_value < 0.05)
        })
        .count();
    assert!(
        low <= 6,
        "{low} of 40 ramp p-values below 0.05 without a ramp"
    );
}

/// The dropouts test on the time stamps: one missing slot against simulations that never
/// drop passes; none does not; a count inside the simulations' own spread does not.
#[test]
fn dropouts_test_counts_missing_slots() {
    use host_sim::gap::evidence::dropouts_outcome;
    let never = [0.0; 12];
    assert!(dropouts_outcome(1.0, &never).passed);
    assert!(!dropouts_outcome(0.0, &never).passed);
    let some = [4.0, 6.0, 5.0, 3.0, 7.0, 5.0, 4.0, 6.0];
    let t = dropouts_outcome(8.0, &some);
    assert!(
        !t.passed,
        "z {} (null mean {}, sd {})",
        t.z, t.null_mean, t.null_sd
    );
    assert!(dropouts_outcome(40.0, &some).passed);
}

/// The spikes test's count: 180 000 samples of Gaussian noise have ~10 running-median
/// residuals beyond the candidate's 6 robust sigma but none beyond the test's 10; four
/// 15-sigma spikes are all counted, and against simulations without any they pass.
#[test]
fn spikes_test_counts_outliers_gaussian_noise_has_none() {
    use host_sim::gap::effects::outliers;
    use host_sim::gap::evidence::{spikes_outcome, SPIKE_TEST_SIGMAS};
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let mut y: Vec<f64> = (0..180_000)
        .map(|_| StandardNormal.sample(&mut rng))
        .collect();
    let all = [(0, y.len())];
    let (n6, _) = outliers(&y, &all, 6.0);
    assert!((2.0..40.0).contains(&n6), "{n6} beyond 6 robust sigma");
    assert_eq!(outliers(&y, &all, SPIKE_TEST_SIGMAS).0, 0.0);
    for k in [10_000, 50_000, 90_000, 170_000] {
        y[k] += 15.0;
    }
    let (count, sizes) = outliers(&y, &all, SPIKE_TEST_SIGMAS);
    assert_eq!(count, 4.0, "{sizes:?}");
    assert!(spikes_outcome(count, &[0.0; 12]).passed);
    assert!(!spikes_outcome(0.0, &[0.0; 12]).passed);
    // Inside the simulations' own spread: not passed.
    assert!(!spikes_outcome(5.0, &[3.0, 5.0, 4.0, 6.0, 2.0, 5.0]).passed);
}

/// A record that turns (a 20 deg/s turn for 5 s in 200 s at 100 Hz) is not diagnosed as a
/// gyro's drift: refused in one line naming the file, the time of the turn and the way out
/// (`--reference-column`); the same record with the turn as its reference passes the check.
#[test]
fn a_record_that_turns_is_said_not_static() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("turn.csv");
    let turn = |i: usize| {
        if (10_000..10_500).contains(&i) {
            20.0
        } else {
            0.0
        }
    };
    write_csv(
        &p,
        (0..20_000).map(|i| {
            format!(
                "{},{},{}",
                i as f64 * 0.01,
                turn(i) + 0.001 * ((i * 7919) % 13) as f64,
                turn(i)
            )
        }),
        "t_s,rate_dps,table_dps",
    );
    let err = gap_refused(&p, dir.path());
    assert!(
        err.contains("turn.csv: not a static record: its 1-s mean from t = 100.0 s")
            && err.contains("--reference-column"),
        "{err}"
    );
    let (rec, _) = gap::read_rec(
        &p,
        &ReadOptions {
            reference_column: Some("table_dps".into()),
            ..ReadOptions::default()
        },
    )
    .expect("read");
    assert_eq!(gap::not_static(&rec), None);
    let (rec, _) = gap::read_rec(&p, &ReadOptions::default()).expect("read");
    assert!(gap::not_static(&rec).is_some());
}

/// `host-sim simulate` of the gyro file `gyro_toml` for 1200 s with `seed`, written under
/// `dir`: its `(t_s, rate_dps)` rows alone (the simulator's truth columns would give the
/// answer away).
fn simulated_rate(dir: &std::path::Path, gyro_toml: &str, seed: &str) -> Vec<(f64, f64)> {
    let gyro = dir.join(format!("gyro-{seed}.toml"));
    std::fs::write(&gyro, gyro_toml).expect("gyro file");
    let sim = dir.join(format!("sim-{seed}.csv"));
    Command::cargo_bin("host-sim")
        .expect("binary")
        .args(["simulate", "--duration-s", "1200", "--seed", seed, "--gyro"])
        .arg(&gyro)
        .arg("--output")
        .arg(&sim)
        .assert()
        .success();
    let text = std::fs::read_to_string(&sim).expect("simulated record");
    text.lines()
        .skip(1)
        .map(|l| {
            let mut f = l.split(',');
            let t: f64 = f.next().expect("t_s").parse().expect("t_s");
            let r: f64 = f.next().expect("rate_dps").parse().expect("rate_dps");
            (t, r)
        })
        .collect()
}

/// A plainly visible line whose dedicated test passes is named although the held-out gap
/// falls by less than the null's spread (`null_gap_95 - null_gap_median`): the test is its
/// significance, and its shrink is above its own null shrink. Before, the spread rule was
/// asked of passed tests too and the record got `none` (fresh set 9560001: 25 of 64
/// detectable records missed, among them `sinusoid-9564004`, a line of z 7.1 whose gap fell
/// 2.66 -> 1.42 against a spread of 1.71). The record is the project's simulator's: white
/// noise, flicker and a random walk (0.06 deg/sqrt(h), 1.5 deg/h, 0.5 deg/h/sqrt(h)) at
/// 50 Hz for 1200 s, with a line of 2.35 deg/h at 0.37 Hz (0.39 of the white noise's
/// sample standard deviation, a periodogram peak 16 times its noise amplitude). The fall is
/// the features' (the candidate's own gap before holds its held-out check, `gap::check`).
#[test]
fn a_passed_test_names_a_line_whose_gap_fall_is_within_the_spread() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rows = simulated_rate(
        dir.path(),
        "sample_rate_hz = 50.0\narw_deg_per_rth = 0.06\nbias_instability_dph = 1.5\n\
         rrw_dph_per_rth = 0.5\n[noise]\nsine_amplitude_dph = 2.35\nsine_freq_hz = 0.37\n\
         sine_phase_deg = 20.0\n",
        "2",
    );
    let p = dir.path().join("line.csv");
    write_csv(
        &p,
        rows.iter().map(|(t, r)| format!("{t},{r}")),
        "t_s,rate_dps",
    );
    let v = gap_json(
        &p,
        &dir.path().join("line.json"),
        &["--no-task", "--rounds", "1"],
    );
    let g = |k: &str| v[k].as_f64().expect(k);
    let test = v["tests"]
        .as_array()
        .expect("tests")
        .iter()
        .find(|t| t["effect"] == "sinusoid")
        .expect("sinusoid test");
    let z = test["z"].as_f64().expect("z");
    assert!(
        test["passed"] == true && z > 2.0 * test["threshold"].as_f64().expect("threshold"),
        "the line is plainly visible to its test: z {z}"
    );
    let cand = v["candidates"]
        .as_array()
        .expect("candidates")
        .iter()
        .find(|c| c["effect"] == "sinusoid")
        .expect("sinusoid candidate");
    // The features' gap before (the largest group's; the top-level `gap_before` is the
    // candidate's own, with its held-out check) and after: its line's check z after is
    // within the noise, so the gap after is the features'.
    let features_before = v["group_gap_before"]
        .as_object()
        .expect("group_gap_before")
        .values()
        .filter_map(|x| x.as_f64())
        .fold(0.0, f64::max);
    let [_, check_after] = [0, 1].map(|k| cand["heldout_check_z"][k].as_f64().expect("check"));
    let after = cand["gap_after"].as_f64().expect("gap_after");
    assert!(check_after.powi(2) <= after, "check z after {check_after}");
    let fall = features_before - after;
    let spread = g("null_gap_95") - g("null_gap_median");
    // The case the spread rule refused: the gap falls, by less than the null's spread.
    assert!(
        fall > 0.0 && fall <= spread,
        "fall {fall} not within the spread {spread}: the record no longer tests the rule"
    );
    assert_eq!(v["effect"], "sinusoid", "decision: {}", v["decision"]);
    let f_hz = v["params"]["sine_freq_hz"].as_f64().expect("sine_freq_hz");
    assert!((f_hz - 0.37).abs() < 0.005, "line at {f_hz} Hz");
    assert!(
        g("shrink") > cand["null_shrink_95"].as_f64().unwrap_or(0.0).max(0.0),
        "shrink above its own null"
    );
}

/// A passed count test whose outliers or holes all lie in the held-out blocks sizes its
/// candidate before the candidate is simulated: the candidate's simulations carry the
/// spikes or holes, and the held-out gap they leave is not the baseline's. Sized only after
/// the simulations (main 582aa99), the candidate's simulations had none: its `gap_after`
/// equalled `gap_before` exactly, shrink 0.000, and a record with its count test passed at
/// z 10 or 16.7 was named `none` (fresh set 9570001: `spikes-9577001`, 3 outliers, held-out
/// gap 154,623; `dropouts-9578005`, 5 missing slots). The record is the project's
/// simulator's white noise and flicker (0.06 deg/sqrt(h), 1.5 deg/h) at 50 Hz for 1200 s;
/// 3 spikes of 0.2 deg/s (about 28 standard deviations of the white noise), or 5 dropped
/// samples, are put in the held-out blocks 2, 4 and 6 (of six 200-s blocks) alone.
#[test]
fn a_count_test_sizes_its_candidate_before_it_is_simulated() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rows = simulated_rate(
        dir.path(),
        "sample_rate_hz = 50.0\narw_deg_per_rth = 0.06\nbias_instability_dph = 1.5\n",
        "3",
    );
    // Sample indices in the held-out blocks (50 Hz: 200 s is 10,000 samples).
    let spikes = [15_000_usize, 35_017, 55_031];
    let dropped = [15_000_usize, 15_500, 35_017, 55_031, 55_500];
    for (effect, expect_test) in [("spikes", 3.0), ("dropouts", 5.0)] {
        let p = dir.path().join(format!("{effect}.csv"));
        write_csv(
            &p,
            rows.iter()
                .enumerate()
                .filter_map(|(i, &(t, r))| match effect {
                    "spikes" if spikes.contains(&i) => Some(format!("{t},{}", r + 0.2)),
                    "dropouts" if dropped.contains(&i) => None,
                    _ => Some(format!("{t},{r}")),
                }),
            "t_s,rate_dps",
        );
        let v = gap_json(
            &p,
            &dir.path().join(format!("{effect}.json")),
            &["--no-task", "--rounds", "1"],
        );
        let test = v["tests"]
            .as_array()
            .expect("tests")
            .iter()
            .find(|t| t["effect"] == effect)
            .expect("count test");
        assert_eq!(test["passed"], true, "{effect}: {test}");
        assert_eq!(
            test["statistic"].as_f64(),
            Some(expect_test),
            "{effect}: {test}"
        );
        let cand = v["candidates"]
            .as_array()
            .expect("candidates")
            .iter()
            .find(|c| c["effect"] == effect)
            .expect("candidate");
        assert_eq!(
            cand["params"]["excess_count"].as_f64(),
            Some(expect_test),
            "{effect}: sized by its count test, the fit blocks have none: {cand}"
        );
        let before = v["gap_before"].as_f64().expect("gap_before");
        let after = cand["gap_after"].as_f64().expect("gap_after");
        // Main's defect: the candidate's simulations were the baseline's, after == before.
        assert!(
            after < before,
            "{effect}: the candidate's simulations carry the effect: gap {before} -> {after}"
        );
        assert_eq!(v["effect"], effect, "{effect}: decision {}", v["decision"]);
        assert!(v["shrink"].as_f64().expect("shrink") > 0.0);
    }
}

/// One sample slot missing from a fit block: the `dropouts` check counts the whole record
/// (each half held out once: nothing fitted moves a count read from the time stamps), its
/// spread floored as its test's (0.3 slot), so the one slot is found (`gap::check`). With
/// the held-out blocks alone (main 5954413) its check counted 0 and the record was named
/// `none` (fresh set 9620001, `dropouts-9628001`: 1 slot, shrink -0.015). The record is the
/// simulator's white noise at 50 Hz for 1200 s, the slot at 100 s (block 1 of six 200-s
/// blocks, a fit block). The check is a group of its own in a gap that is the largest over
/// groups: one slot (z 3.3, z^2 11) is hidden where another group's gap is above 11 (with
/// flicker of 1.5 deg/h added to this record its drift group is at 21.9, and the record is
/// named `none`).
#[test]
fn one_missing_slot_in_a_fit_block_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rows = simulated_rate(
        dir.path(),
        "sample_rate_hz = 50.0\narw_deg_per_rth = 0.06\n",
        "5",
    );
    let p = dir.path().join("one-slot.csv");
    write_csv(
        &p,
        rows.iter()
            .enumerate()
            .filter(|&(i, _)| i != 5_000)
            .map(|(_, &(t, r))| format!("{t},{r}")),
        "t_s,rate_dps",
    );
    let v = gap_json(
        &p,
        &dir.path().join("one-slot.json"),
        &["--no-task", "--rounds", "1"],
    );
    let cand = v["candidates"]
        .as_array()
        .expect("candidates")
        .iter()
        .find(|c| c["effect"] == "dropouts")
        .expect("candidate");
    let z = cand["heldout_check_z"][0].as_f64().expect("check z");
    assert!(z > 3.0, "the whole record's one slot against 0.3: {cand}");
    assert_eq!(v["effect"], "dropouts", "decision {}", v["decision"]);
}
