//! The simulator as a library: drift bookkeeping, deterministic terms, the flicker floor,
//! timing faults, quantization, the preset file.

use host_sim::allan::{oadev, tau_factors, Taus};
use host_sim::sim::{self, Model, QuantMode, Simulator, EARTH_RATE_DPS, FLICKER_FLOOR};

fn collect(model: &Model, seed: u64, rate_hz: f64, n: usize) -> Vec<sim::Sample> {
    let mut s = Simulator::new(model, seed, rate_hz).expect("valid model");
    (0..n).map(|_| s.next_sample()).collect()
}

#[test]
fn rate_minus_true_minus_drift_is_the_white_noise() {
    let mut m = Model::default();
    m.noise.arw_dps_per_rthz = 2e-3;
    m.noise.bias_instability_dps = 5e-4;
    m.noise.rrw_dps_per_s_rthz = 1e-5;
    m.noise.rate_ramp_dps_per_s = 1e-6;
    m.noise.gm_sigma_dps = 1e-3;
    m.noise.sine_amplitude_dps = 1e-3;
    m.noise.sine_freq_hz = 0.01;
    m.bias.turn_on_sigma_dps = 1e-2;
    m.bias.warmup_dps = 1e-3;
    m.temperature.warmup_rise_c = 5.0;
    m.temperature.bias_dps_per_c = 1e-4;
    m.temperature.shupe_dps_per_c_per_s = 1e-2;
    m.scale_factor.error_ppm = 300.0;
    m.motion.rate_dps = 10.0;
    m.motion.latitude_deg = 45.0;
    let rate_hz = 100.0;
    let samples = collect(&m, 9, rate_hz, 200_000);
    let resid: Vec<f64> = samples
        .iter()
        .map(|s| s.rate_dps - s.true_rate_dps - s.drift_dps)
        .collect();
    let n = resid.len() as f64;
    let mean = resid.iter().sum::<f64>() / n;
    let sd = (resid.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n).sqrt();
    let want = 2e-3 * rate_hz.sqrt();
    assert!((sd / want - 1.0).abs() < 0.01, "sd {sd} vs {want}");
    assert!(mean.abs() < 4.0 * want / n.sqrt(), "mean {mean}");
    // The drift moves (slow terms), the true rate is platform + Earth rate.
    let t = 10.0 + EARTH_RATE_DPS * 45f64.to_radians().sin();
    assert!(samples.iter().all(|s| (s.true_rate_dps - t).abs() < 1e-12));
    let d0 = samples[0].drift_dps;
    assert!(samples.iter().any(|s| (s.drift_dps - d0).abs() > 1e-3));
}

#[test]
fn deterministic_terms_follow_their_formulas() {
    let mut m = Model::default();
    m.noise.rate_ramp_dps_per_s = 2e-5;
    m.bias.turn_on_dps = 0.01;
    m.bias.warmup_dps = 0.002;
    m.bias.warmup_tau_s = 60.0;
    m.temperature.ramp_c_per_s = 0.01;
    m.temperature.cycle_amplitude_c = 2.0;
    m.temperature.cycle_period_s = 100.0;
    m.temperature.warmup_rise_c = 4.0;
    m.temperature.warmup_tau_s = 30.0;
    m.temperature.bias_dps_per_c = 1e-3;
    m.temperature.shupe_dps_per_c_per_s = 0.05;
    m.scale_factor.error_ppm = 1000.0;
    m.scale_factor.quadratic_ppm_per_dps = 10.0;
    m.motion.sine_amplitude_dps = 5.0;
    m.motion.sine_freq_hz = 0.1;
    for s in collect(&m, 1, 10.0, 3000) {
        let t = s.t_s;
        let w = std::f64::consts::TAU / 100.0;
        let temp = 25.0 + 0.01 * t + 2.0 * (w * t).sin() + 4.0 * (1.0 - (-t / 30.0).exp());
        let dtemp = 0.01 + 2.0 * w * (w * t).cos() + 4.0 / 30.0 * (-t / 30.0).exp();
        let truth = 5.0 * (std::f64::consts::TAU * 0.1 * t).sin();
        let sf = truth * 1e-6 * (1000.0 + 10.0 * truth.abs());
        let drift =
            sf + 0.01 + 0.002 * (-t / 60.0).exp() + 2e-5 * t + 1e-3 * (temp - 25.0) + 0.05 * dtemp;
        assert!((s.temp_c - temp).abs() < 1e-9);
        assert!((s.drift_dps - drift).abs() < 1e-12, "t {t}");
        assert!((s.rate_dps - truth - drift).abs() < 1e-12);
    }
}

#[test]
fn simulated_flicker_floor_is_0_664_b() {
    // B only, 4 h at 10 Hz: mean ADEV over tau 12.8 .. 102.4 s within 10 % of 0.664 B.
    let mut m = Model::default();
    m.noise.bias_instability_dps = 1e-3;
    m.noise.flicker_tau_min_s = 0.5;
    m.noise.flicker_tau_max_s = 1e6;
    for seed in [1u64, 2, 3] {
        let rate: Vec<f64> = collect(&m, seed, 10.0, 144_000)
            .iter()
            .map(|s| s.rate_dps)
            .collect();
        let ms: Vec<usize> = tau_factors(rate.len(), Taus::Octave)
            .into_iter()
            .filter(|&k| (128..=1024).contains(&k))
            .collect();
        let pts = oadev(&rate, 0.1, &ms);
        let mean = pts.iter().map(|p| p.adev_dps).sum::<f64>() / pts.len() as f64;
        let ratio = mean / (FLICKER_FLOOR * 1e-3);
        eprintln!("seed {seed}: floor / 0.664 B = {ratio:.3}");
        assert!((ratio - 1.0).abs() < 0.1, "seed {seed}: {ratio}");
    }
    // And the analytic curve of the bank, over its flat band.
    for tau in [10.0, 50.0, 500.0, 5000.0, 50_000.0, 100_000.0] {
        let r = sim::flicker_adev(1.0, 0.5, 1e6, tau) / FLICKER_FLOOR;
        assert!((r - 1.0).abs() < 0.02, "tau {tau}: {r}");
    }
}

#[test]
fn drops_jitter_and_clock_error() {
    let mut m = Model::default();
    m.noise.arw_dps_per_rthz = 1e-3;
    m.faults.drop_probability = 0.1;
    m.timing.jitter_rms_s = 1e-3;
    m.timing.rate_error_ppm = 500.0;
    let s = collect(&m, 3, 100.0, 20_000);
    assert!(s.windows(2).all(|w| w[1].t_s > w[0].t_s));
    assert!(s[0].t_s >= 0.0);
    let dt = 1.0 / (100.0 * (1.0 + 500e-6));
    let gaps = s
        .windows(2)
        .filter(|w| w[1].t_s - w[0].t_s > 1.5 * dt)
        .count();
    let frac = gaps as f64 / s.len() as f64;
    assert!((frac - 0.1).abs() < 0.015, "gap fraction {frac}");
    let last = s.last().expect("samples");
    assert!((last.t_s - last.index as f64 * dt).abs() <= 0.45 * dt + 1e-12);
    // Jitter is there: steps are not all equal.
    assert!(s
        .windows(2)
        .any(|w| ((w[1].t_s - w[0].t_s) - dt).abs() > 1e-4));
}

#[test]
fn spikes_are_not_drift() {
    let mut m = Model::default();
    m.faults.spike_probability = 0.01;
    m.faults.spike_amplitude_dps = 5.0;
    let s = collect(&m, 4, 100.0, 10_000);
    let spikes = s
        .iter()
        .filter(|x| (x.rate_dps.abs() - 5.0).abs() < 1e-12)
        .count();
    assert!((50..=150).contains(&spikes), "{spikes}");
    assert!(s.iter().all(|x| x.drift_dps == 0.0));
}

#[test]
fn quantization_round_and_angle() {
    let q = 60.0 / 32768.0;
    let mut m = Model::default();
    m.noise.arw_dps_per_rthz = 1e-3;
    m.bias.turn_on_dps = 0.3 * q;
    m.quantization.quantum_dps = q;
    m.full_scale_dps = Some(60.0);
    let round = collect(&m, 5, 100.0, 5000);
    assert!(round.iter().all(|s| (s.rate_dps / q).fract() == 0.0));
    m.quantization.mode = QuantMode::Angle;
    // Angle mode: the integrated angle stays within half a count of the unquantized one.
    let mut exact = m.clone();
    exact.quantization.quantum_dps = 0.0;
    let a = collect(&m, 5, 100.0, 5000);
    let e = collect(&exact, 5, 100.0, 5000);
    let (mut sa, mut se) = (0.0, 0.0);
    for (x, y) in a.iter().zip(&e) {
        assert_eq!((x.rate_dps / q).fract(), 0.0);
        sa += x.rate_dps;
        se += y.rate_dps;
        assert!((sa - se).abs() <= 0.5 * q + 1e-12);
    }
    // Saturation at full scale.
    m.bias.turn_on_dps = 100.0;
    assert!(collect(&m, 5, 100.0, 10).iter().all(|s| s.rate_dps == 60.0));
}

#[test]
fn preset_parses_and_every_value_says_where_it_comes_from() {
    let p = sim::preset("ecore2000").expect("preset");
    assert_eq!(p.full_scale_dps, Some(60.0));
    assert_eq!(p.quantization.quantum_dps, 60.0 / 32768.0);
    assert_eq!(p.sample_rate_hz, Some(100.0));
    // Bias stability below 2 deg/h: the Allan floor 0.664 B.
    assert!(FLICKER_FLOOR * p.noise.bias_instability_dps * 3600.0 < 2.0);
    for line in host_sim::gyro::BUILTIN[0].2.lines() {
        let code = line.split('#').next().unwrap_or("");
        // The name and the records' temperature column are not figures of the gyro.
        if code.contains('=') && !code.starts_with("name") && !code.starts_with("column") {
            let comment = line.split_once('#').map_or("", |c| c.1);
            assert!(
                [
                    "[spec]",
                    "[brief]",
                    "ASSUMED",
                    "model construction",
                    "static"
                ]
                .iter()
                .any(|tag| comment.contains(tag)),
                "value without a source or ASSUMED mark: {line}"
            );
        }
    }
    assert!(sim::preset("nope").is_err());
    // The same model through a file-like round trip gives the same samples.
    let a = collect(&p, 11, 100.0, 1000);
    let b = collect(&p, 11, 100.0, 1000);
    assert_eq!(a, b);
}
