//! Term selection in the Allan fit: a term is reported only when the data support it.
//!
//! 10 h at 10 Hz of white rate noise plus rate random walk (no quantization, no flicker, no
//! ramp): the fit must report N and K and neither Q nor R (the previous NNLS-only fit
//! reported Q at 3.7 sigma and R at 2.9 sigma on such a record); each term carries the
//! reason. Control (so the check can fail): the same record with a strong rate ramp added
//! must report R.

use host_sim::allan::{analyse, edf, fit::Kind, tau_factors, Taus};
use host_sim::sim::{Model, Simulator};

const RATE_HZ: f64 = 10.0;
const HOURS: f64 = 10.0;

fn fit_of(ramp_dps_per_s: f64, seed: u64) -> host_sim::allan::fit::Fit {
    let mut m = Model::default();
    m.noise.arw_dps_per_rthz = 0.1 / 60.0; // 0.1 deg/sqrt(h)
                                           // 2 deg/h/sqrt(h): RRW crosses ARW at tau = sqrt(3) N / K = 78 s, so K shapes the
                                           // octave taus 160 s - 13 107 s (with K four times smaller it crosses at 1250 s and the
                                           // last three points cannot tell it from a flicker floor: a test of that would be noise).
    m.noise.rrw_dps_per_s_rthz = 2.0 / 216_000.0;
    m.noise.rate_ramp_dps_per_s = ramp_dps_per_s;
    let mut sim = Simulator::new(&m, seed, RATE_HZ).expect("valid model");
    let n = (HOURS * 3600.0 * RATE_HZ) as usize;
    let rate: Vec<f64> = (0..n).map(|_| sim.next_sample().rate_dps).collect();
    let ms = tau_factors(n, Taus::Octave);
    analyse(&rate, 1.0 / RATE_HZ, &ms, false, edf::ONE_SIGMA)
        .expect("fit")
        .1
}

fn active(f: &host_sim::allan::fit::Fit, k: Kind) -> bool {
    f.get(k).is_some_and(|t| t.active)
}

#[test]
fn white_noise_and_rrw_report_no_quantization_and_no_ramp() {
    for seed in [1u64, 2, 3] {
        let f = fit_of(0.0, seed);
        for t in &f.terms {
            eprintln!(
                "seed {seed}: {:?} active {} - {}",
                t.term, t.active, t.selection
            );
            assert!(!t.selection.is_empty(), "{:?}: no selection reason", t.term);
        }
        assert!(active(&f, Kind::Arw), "seed {seed}: N missing");
        assert!(active(&f, Kind::Rrw), "seed {seed}: K missing");
        assert!(!active(&f, Kind::Quantization), "seed {seed}: Q reported");
        assert!(!active(&f, Kind::RateRamp), "seed {seed}: R reported");
    }
}

#[test]
fn a_real_ramp_is_reported() {
    // 20 deg/h per h: over 10 h the ramp's AVAR (R^2 tau^2 / 2) is far above the RRW's.
    let f = fit_of(20.0 / 3600.0 / 3600.0, 1);
    assert!(
        active(&f, Kind::RateRamp),
        "ramp not reported: {:?}",
        f.get(Kind::RateRamp).map(|t| t.selection.clone())
    );
}
