//! Overlapping ADEV against allantools (vectors from `scripts/gen_allan_vectors.py`).

use host_sim::allan::{oadev, oavar_phase, phase_from_rate};
use serde::Deserialize;

#[derive(Deserialize)]
struct Case {
    name: String,
    rate_hz: f64,
    data: Vec<f64>,
    m: Vec<usize>,
    oadev: Vec<f64>,
    n: Vec<usize>,
}

#[derive(Deserialize)]
struct Doc {
    cases: Vec<Case>,
}

#[test]
fn oadev_matches_allantools_within_1e9() {
    let text = include_str!("data/allan_vectors.json");
    let doc: Doc = serde_json::from_str(text).expect("vectors parse");
    assert!(doc.cases.len() >= 3);
    let mut checked = 0;
    for c in &doc.cases {
        let tau0 = 1.0 / c.rate_hz;
        let phase = phase_from_rate(&c.data, tau0);
        let pts = oadev(&c.data, tau0, &c.m);
        assert_eq!(pts.len(), c.m.len(), "{}", c.name);
        for (i, &m) in c.m.iter().enumerate() {
            let (avar, n) = oavar_phase(&phase, tau0, m).expect("m in range");
            assert_eq!(n, c.n[i], "{} m={m}: number of differences", c.name);
            let rel = (avar.sqrt() / c.oadev[i] - 1.0).abs();
            assert!(
                rel < 1e-9,
                "{} m={m}: {} vs allantools {} (rel {rel:e})",
                c.name,
                avar.sqrt(),
                c.oadev[i]
            );
            assert_eq!(pts[i].adev_dps, avar.sqrt());
            checked += 1;
        }
    }
    assert!(checked >= 50, "{checked}");
}

#[test]
fn a_wrong_adev_would_fail() {
    // The comparison is sensitive: the non-overlapping estimator differs at m > 1.
    let text = include_str!("data/allan_vectors.json");
    let doc: Doc = serde_json::from_str(text).expect("vectors parse");
    let c = &doc.cases[0];
    let tau0 = 1.0 / c.rate_hz;
    let phase = phase_from_rate(&c.data, tau0);
    let i = c.m.iter().position(|&m| m == 16).expect("m = 16 present");
    let m = 16;
    let mut s = 0.0;
    let mut k = 0usize;
    let mut j = 0;
    while j + 2 * m < phase.len() {
        let d = phase[j + 2 * m] - 2.0 * phase[j + m] + phase[j];
        s += d * d;
        k += 1;
        j += m;
    }
    let tau = m as f64 * tau0;
    let non_overlapping = (s / (2.0 * k as f64 * tau * tau)).sqrt();
    assert!((non_overlapping / c.oadev[i] - 1.0).abs() > 1e-6);
}
