//! Hand-checked numbers for the scores and the baselines.

use super::*;

fn close(a: f64, b: f64, tol: f64) {
    assert!((a - b).abs() <= tol, "{a} vs {b}");
}

#[test]
fn heading_is_the_trapezoid_integral_and_its_rms() {
    let mut h = HeadingAcc::new();
    // errors 1, 1, 3 deg/s at t = 0, 1, 2: heading 0, 1, 1 + 2 = 3 deg.
    let got: Vec<f64> = [(0.0, 1.0), (1.0, 1.0), (2.0, 3.0)]
        .iter()
        .map(|&(t, c)| h.push(t, c, 0.0, 0.0, 0.0, true))
        .collect();
    assert_eq!(got, vec![0.0, 1.0, 3.0]);
    let s = h.scores();
    close(s.heading_rms_deg, (10.0f64 / 3.0).sqrt(), 1e-12);
    assert_eq!(s.heading_final_deg, 3.0);
    assert_eq!(s.heading_max_abs_deg, 3.0);
}

#[test]
fn e_truth_is_split_still_moving_in_deg_per_h() {
    let mut h = HeadingAcc::new();
    let dph = 1.0 / 3600.0;
    h.push(0.0, 0.0, 0.0, 2.0 * dph, 0.0, false); // still, 2 deg/h
    h.push(1.0, 0.0, 0.0, 0.0, 4.0 * dph, false); // still, -4 deg/h
    h.push(2.0, 0.0, 0.0, 3.0 * dph, 0.0, true); // moving, 3 deg/h
    let s = h.scores();
    close(s.e_truth_still_dph.expect("still"), 10f64.sqrt(), 1e-9);
    close(s.e_truth_moving_dph.expect("moving"), 3.0, 1e-9);
    close(s.e_truth_dph.expect("all"), (29.0f64 / 3.0).sqrt(), 1e-9);
}

#[test]
fn detector_rates() {
    let mut d = DetectorAcc::default();
    let moving = [true, true, false, false, false];
    let called = [true, false, false, true, true];
    for (m, c) in moving.iter().zip(called) {
        d.push(*m, c);
    }
    let s = d.scores();
    assert_eq!(s.false_still_rate, Some(0.5));
    close(s.missed_still_rate.expect("still"), 1.0 / 3.0, 1e-15);
    assert_eq!(DetectorAcc::default().scores().false_still_rate, None);
}

#[test]
fn alignment_bias_holds_the_initial_still_mean() {
    let mut a = AlignmentBias::default();
    let got: Vec<f64> = [
        (1.0, true),
        (2.0, true),
        (3.0, true),
        (10.0, false),
        (20.0, true),
    ]
    .iter()
    .map(|&(r, s)| a.push(0.0, r, None, s))
    .collect();
    assert_eq!(got, vec![0.0, 1.0, 1.5, 2.0, 2.0]);
    assert_eq!(a.push(0.0, 5.0, None, true), 2.0);
}

#[test]
fn gated_kalman_updates_only_when_still_and_grows_in_motion() {
    let mut k = GatedKalman::new(0.5, 1.0);
    assert_eq!(k.push(0.0, 2.0, None, true), 0.0); // starts: b = 2, p = r = 1
    assert_eq!(k.push(0.0, 100.0, None, false), 2.0); // motion: p = 1.5, b held
    close(k.variance_dps2(), 1.5, 1e-15);
    assert_eq!(k.push(0.0, 4.0, None, true), 2.0); // p = 2, gain 2/3: b = 2 + 4/3
    close(k.push(0.0, 0.0, None, false), 2.0 + 4.0 / 3.0, 1e-12);
    close(k.variance_dps2(), 2.0 / 3.0 + 0.5, 1e-12);
}

#[test]
fn thermal_kalman_learns_the_temperature_slope_at_rest() {
    // Drift 0.01 + 0.002 (T - 20), T from 20 to 40 deg C over 2000 s, no noise, all still.
    let cfg = ThermalKalmanConfig {
        q_dps2: 0.0,
        r_dps2: 1e-6,
        c1_sigma_dps_per_c: 0.01,
        c2_sigma_dps_per_c_per_s: 0.0,
        dtemp_tau_s: 10.0,
    };
    let mut k = ThermalKalman::new(cfg);
    let mut est = 0.0;
    for i in 0..2000 {
        let t = i as f64;
        let temp = 20.0 + 0.01 * t;
        est = k.push(t, 0.01 + 0.002 * (temp - 20.0), Some(temp), true);
    }
    close(k.coefficients().c1_dps_per_c, 0.002, 1e-6);
    close(est, 0.01 + 0.002 * 19.99, 1e-5);
    // In motion it predicts from the temperature: T = 45 -> 0.01 + 0.05.
    close(k.push(2000.0, 50.0, Some(45.0), false), 0.06, 1e-4);
}

#[test]
fn fit_thermal_recovers_coefficients_with_per_record_intercepts() {
    // Two records, intercepts 1 and -3 deg/s, c1 = 0.002, c2 = 0.5; T piecewise so that
    // T and dT/dt are not collinear.
    let rec = |b: f64, slope: f64| -> Vec<(f64, f64, f64, bool)> {
        let mut tr = TempRate::new(5.0);
        (0..3000)
            .map(|i| {
                let t = i as f64;
                let temp = 20.0 + slope * t + 3.0 * (t / 300.0).sin();
                let d = tr.push(t, temp);
                (t, b + 0.002 * (temp - 20.0) + 0.5 * d, temp, true)
            })
            .collect()
    };
    let fit = fit_thermal(&[rec(1.0, 0.004), rec(-3.0, -0.002)], 5.0).expect("fit");
    close(fit.c1_dps_per_c, 0.002, 1e-9);
    close(fit.c2_dps_per_c_per_s, 0.5, 1e-6);
    assert_eq!(fit_thermal(&[], 5.0), None);
}

#[test]
fn run_scores_a_turn_that_the_alignment_bias_keeps_out() {
    // 10 s still with drift 0.1 deg/s, then a 10 s turn at 9 deg/s, 1 Hz.
    let n = 20;
    let rec = NavRecord {
        t_s: (0..n).map(f64::from).collect(),
        rate_dps: (0..n).map(|i| if i < 10 { 0.1 } else { 9.1 }).collect(),
        temp_c: None,
        true_rate_dps: (0..n).map(|i| if i < 10 { 0.0 } else { 9.0 }).collect(),
        drift_dps: vec![0.1; n as usize],
        moving: (0..n).map(|i| i >= 10).collect(),
    };
    let still = rec.still_truth();
    let none = run(&rec, &mut NoCompensation, &still);
    close(none.scores.heading_final_deg, 1.9, 1e-12);
    let align = run(&rec, &mut AlignmentBias::default(), &still);
    // First sample has no estimate: its error 0.1 over the first half step.
    close(align.scores.heading_final_deg, 0.05, 1e-12);
    close(align.scores.e_truth_moving_dph.expect("moving"), 0.0, 1e-9);
}

#[test]
fn tuner_picks_the_grid_point_with_the_least_heading_rms() {
    // Drift that steps at every stop: a larger q re-converges faster and wins.
    let mut t_s = Vec::new();
    let mut rate = Vec::new();
    let mut drift = Vec::new();
    let mut moving = Vec::new();
    for i in 0..4000 {
        let t = i as f64 * 0.1;
        let seg = (t / 50.0) as usize;
        let d = 0.01 * seg as f64;
        let m = seg % 2 == 1;
        t_s.push(t);
        drift.push(d);
        rate.push(d + if m { 1.0 } else { 0.0 });
        moving.push(m);
    }
    let rec = NavRecord {
        true_rate_dps: moving.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect(),
        t_s,
        rate_dps: rate,
        temp_c: None,
        drift_dps: drift,
        moving,
    };
    let grid = log_grid(1e-12, 1e-4, 2);
    assert_eq!(grid.len(), 17);
    close(grid[2], 1e-11, 1e-24);
    let t = tune_gated_q(std::slice::from_ref(&rec), 1e-4, &grid).expect("tuned");
    let min = t.grid.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    assert_eq!(t.heading_rms_deg, min);
    assert!(t.q_dps2 > 1e-9, "{}", t.q_dps2);
    assert!(tune_gated_q(&[], 1e-4, &grid).is_none());
}
