//! `gap`'s result in short lines a user reads: what the held-out gap is, each round's
//! effect with the gap before and after and the null it is judged against, what stays
//! unexplained, the spikes and holes with their times. Every figure is one of the JSON's
//! (`rounds`, `unexplained`, `time`), rounded for reading.

use super::rounds::Outcome;
use super::Diagnosis;

/// At most this many spike or hole times are listed (the JSON has them all).
pub const MAX_TIMES: usize = 12;

/// A number with 4 significant digits (all the units of a larger one), in plain notation
/// from 0.001 to 1e6, else in e-notation.
pub fn num(x: f64) -> String {
    let a = x.abs();
    if !x.is_finite() {
        format!("{x}")
    } else if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e6).contains(&a) {
        format!("{x:.3e}")
    } else {
        // 4 significant digits (at least the units).
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        format!("{x:.decimals$}")
    }
}

fn times(t: &[f64]) -> String {
    let mut s: Vec<String> = t
        .iter()
        .take(MAX_TIMES)
        .map(|v| format!("{v:.2}"))
        .collect();
    if t.len() > MAX_TIMES {
        s.push(format!("... ({} more)", t.len() - MAX_TIMES));
    }
    s.join(", ")
}

/// What the baseline does with the record's own colour above the effects' band
/// ([`super::colour`]), when it was fitted: the shaping or why it is white.
pub fn colour_line(d: &Diagnosis) -> Option<String> {
    match (&d.colour, &d.colour_fit) {
        (Some(c), _) => Some(format!(
            "  the model's white noise is shaped by the record's own colour above {} Hz (round 1; fitted again while the baseline is): white level x{}, power gain {} at {} Hz to {} at {} Hz (departure {} sd)",
            num(c.boundary_hz),
            num(c.white_level),
            num(c.min_gain.0),
            num(c.min_gain.1),
            num(c.max_gain.0),
            num(c.max_gain.1),
            num(c.gate_sds)
        )),
        (None, Some(f)) => Some(format!("  the model's white noise stays white: {}", f.detail)),
        _ => None,
    }
}

/// What the baseline does with the record's own value distribution
/// ([`super::marginal`]), when it was fitted: the map, or why the white term stays Gaussian
/// (only said when the record is platykurtic beyond the simulations' spread, 4 standard
/// errors).
pub fn marginal_line(d: &Diagnosis) -> Option<String> {
    match (&d.marginal, &d.marginal_fit) {
        (Some(m), _) => Some(format!(
            "  the model's white noise has the record's own platykurtic distribution: a random-phase sinusoid of {} of its variance plus a Gaussian (white term's excess kurtosis {}); the record's {} +- {} ({} sd below 0; quantum {} of its sd, white share {})",
            num(m.rho),
            num(m.white_excess_kurtosis),
            num(m.excess_kurtosis),
            num(m.se),
            num(m.gate_sds),
            num(m.quantum_of_sd),
            num(m.white_share)
        )),
        (None, Some(f)) if f.gate_sds.abs() > 4.0 => Some(format!(
            "  the model's white noise stays Gaussian: {}",
            f.detail
        )),
        _ => None,
    }
}

/// The lines, without the record's name (the caller puts it first).
pub fn lines(out: &Outcome) -> Vec<String> {
    let f = &out.first;
    let mut v = vec![
        "held-out gap = mean squared z-score of the worst feature group (Allan deviation, PSD, value distribution, window means, drift) of held-out blocks 1, 3, 5 of 6".to_string(),
        "  z = (record - median of the model's simulations) / their seed-to-seed spread; about 1 when the model describes the record".to_string(),
        format!(
            "  the model's own simulations score median {}, 95 % {} (the null); first model: {}",
            num(f.null_gap_median),
            num(f.null_gap_95),
            f.baseline_source
        ),
    ];
    v.extend(colour_line(f));
    v.extend(marginal_line(f));
    for r in &out.rounds {
        let need = r.null_shrink_95.map_or(0.0, |q| q.max(0.0));
        if r.effect == "none" {
            v.push(format!(
                "round {}: none named; gap {} (null 95 % {}); {}",
                r.round,
                num(r.gap_before),
                num(r.null_gap_95),
                r.best_candidate
                    .as_deref()
                    .map_or("no candidate passes the rule".to_string(), |b| {
                        format!("best candidate {b}, not named")
                    })
            ));
        } else {
            let (fall, spread) = (
                r.gap_before - r.gap_after,
                r.null_gap_95 - r.null_gap_median,
            );
            // A name by its passed dedicated test is not asked for a fall above the spread.
            let versus = if fall > spread { ">" } else { "<=" };
            let by_test = if fall > spread {
                ""
            } else {
                " (its test passed)"
            };
            v.push(format!(
                "round {}: {} named; gap {} -> {} (null 95 % {}): falls {} {versus} null spread {}{by_test}, shrink {} > {} needed",
                r.round,
                r.effect,
                num(r.gap_before),
                num(r.gap_after),
                num(r.null_gap_95),
                num(fall),
                num(spread),
                num(r.shrink),
                num(need)
            ));
            for (k, p) in r.params.iter().flatten() {
                let ci = r.params_ci95.as_ref().and_then(|c| c.get(k));
                let sd = r.params_sigma.as_ref().and_then(|c| c.get(k));
                v.push(match (ci, sd) {
                    (Some([lo, hi]), _) => {
                        format!("  {k} = {} (95 %: {} to {})", num(*p), num(*lo), num(*hi))
                    }
                    (None, Some(e)) => format!("  {k} = {} +- {}", num(*p), num(*e)),
                    (None, None) => format!("  {k} = {}", num(*p)),
                });
            }
            if !r.applied.is_empty() {
                v.push(format!("  next round: {}", r.applied));
            }
            if !r.spike_times_s.is_empty() {
                v.push(format!(
                    "  spikes: {} samples at t = {} s",
                    r.spike_times_s.len(),
                    times(&r.spike_times_s)
                ));
            }
        }
    }
    v.push(format!("stopped: {}", out.stopped));
    if out.unexplained.is_empty() {
        v.push(format!(
            "unexplained: nothing (every feature group within its null's 95 %; final gap {}, null 95 % {})",
            num(out.final_gap),
            num(out.final_null_gap_95)
        ));
    } else {
        // At the cap the last round's effect is named but not applied: its groups are
        // those before it.
        let last = out.rounds.last().filter(|r| r.effect != "none");
        v.push(match last {
            Some(r) => format!(
                "unexplained before round {}'s {} (not applied; gap {}, with it {}, null 95 % {}):",
                r.round,
                r.effect,
                num(r.gap_before),
                num(r.gap_after),
                num(r.null_gap_95)
            ),
            None => format!(
                "unexplained (final gap {}, null 95 % {}):",
                num(out.final_gap),
                num(out.final_null_gap_95)
            ),
        });
        for u in &out.unexplained {
            v.push(format!(
                "  {}: gap {} (null 95 % {}){}",
                u.group,
                num(u.gap),
                num(u.null_gap_95),
                if u.what.is_empty() {
                    String::new()
                } else {
                    format!(": {}", u.what)
                }
            ));
        }
    }
    let t = &f.time;
    if t.gap_count > 0 {
        let at: Vec<f64> = t.gaps.iter().map(|g| g.0).collect();
        v.push(format!(
            "holes in t_s: {} ({} missing samples) after t = {} s{}",
            t.gap_count,
            num(t.missing_slots),
            times(&at),
            if t.gap_count > at.len() {
                format!(" (the first {} listed)", at.len().min(MAX_TIMES))
            } else {
                String::new()
            }
        ));
    }
    v
}
