//! Term recovery: simulate 10 h with known ARW, bias instability and RRW, fit them back.
//!
//! Record: 10 h at 10 Hz (360 000 samples; the rate is reduced from the E-Core's 100 Hz to
//! keep the debug-build test short; the terms are defined per unit time, so the rate does not
//! change them). Truth: B = 1 deg/h; N chosen so that ARW meets the flicker floor at
//! tau = 10 s, K so that RRW meets it at tau = 300 s, so each term dominates a stretch of
//! the octave taus (0.1 s .. 13 107 s). Flicker bank 0.5 s .. 1e6 s (floor flat within 2 % from 10 s, 4 % from 5 s).
//! Tolerances: ARW 5 %, bias instability 15 %, RRW 25 %, for seeds 1 to 5.

use host_sim::allan::{analyse, edf, fit::Kind, tau_factors, Taus};
use host_sim::sim::{Model, Simulator, FLICKER_FLOOR};

const RATE_HZ: f64 = 10.0;
const HOURS: f64 = 10.0;
const B_DPS: f64 = 1.0 / 3600.0;

fn truth() -> (f64, f64, f64) {
    let floor = FLICKER_FLOOR * B_DPS;
    let n = floor * 10f64.sqrt();
    let k = floor * (3.0f64 / 300.0).sqrt();
    (n, B_DPS, k)
}

fn model() -> Model {
    let (n, b, k) = truth();
    let mut m = Model::default();
    m.noise.arw_dps_per_rthz = n;
    m.noise.bias_instability_dps = b;
    m.noise.rrw_dps_per_s_rthz = k;
    m.noise.flicker_tau_min_s = 0.5;
    m.noise.flicker_tau_max_s = 1e6;
    m
}

/// Relative errors (ARW, B, RRW) of the fit of one simulated record.
fn recovery(model: &Model, seed: u64) -> [f64; 3] {
    let mut sim = Simulator::new(model, seed, RATE_HZ).expect("valid model");
    let n = (HOURS * 3600.0 * RATE_HZ) as usize;
    let rate: Vec<f64> = (0..n).map(|_| sim.next_sample().rate_dps).collect();
    let ms = tau_factors(n, Taus::Octave);
    let (_, fit) = analyse(&rate, 1.0 / RATE_HZ, &ms, false, edf::ONE_SIGMA).expect("fit");
    let (tn, tb, tk) = truth();
    let got = |k: Kind| fit.get(k).map_or(0.0, |t| t.value);
    [
        got(Kind::Arw) / tn - 1.0,
        got(Kind::BiasInstability) / tb - 1.0,
        got(Kind::Rrw) / tk - 1.0,
    ]
}

#[test]
fn arw_bias_instability_rrw_are_recovered() {
    let limits = [0.05, 0.15, 0.25];
    let m = model();
    for seed in [1u64, 2, 3, 4, 5] {
        let e = recovery(&m, seed);
        eprintln!(
            "seed {seed}: ARW {:+.2} %, B {:+.2} %, RRW {:+.2} %",
            100.0 * e[0],
            100.0 * e[1],
            100.0 * e[2]
        );
        for (i, name) in ["ARW", "bias instability", "RRW"].iter().enumerate() {
            assert!(
                e[i].abs() < limits[i],
                "seed {seed}: {name} off by {:.1} % (limit {:.0} %)",
                100.0 * e[i],
                100.0 * limits[i]
            );
        }
    }
}

#[test]
fn the_recovery_check_can_fail() {
    // Same records, but the simulator is given B 30 % too large: the check must see it.
    let mut m = model();
    m.noise.bias_instability_dps *= 1.3;
    let e = recovery(&m, 1);
    assert!(
        e[1].abs() > 0.15,
        "B error {:.1} % not detected",
        100.0 * e[1]
    );
}
