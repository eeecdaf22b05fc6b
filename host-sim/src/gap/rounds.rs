//! `gap --rounds N`: the named effect is added to the model (or taken out of the record)
//! and the record diagnosed again, until `none` or `N` rounds.
//!
//! How a named effect enters the next round:
//! - `warmup` goes into the model (which the drift tests subtract before testing again; a
//!   second warm-up is subtracted from the record);
//! - `rate_ramp` leaves the record: its fitted slope, then the fit over all samples of what
//!   is left (`less_ramp`), and every later simulation has its own fit on time taken out
//!   too (`effects::TakenOut`), so the record and the simulations hold the same in-sample
//!   residual (a link named later keeps the ramp's fit out of both); the model takes the
//!   N, B, K its candidate was refitted with;
//! - the other deterministic effects are subtracted from the record's rate with their fitted
//!   parameters: `temperature` (coefficients times `temp_c - reference` and times its rate of change,
//!   from 10-s windows as the drift test reads it), `sinusoid`, `scale_factor` (times the
//!   reference rate); after a `temperature`, every later simulation has its own fit on the
//!   link's regressors taken out too (`effects::TakenOut`: the fit took part of the
//!   record's own slow wander with it), and so has the record, after the named link: what
//!   the named (whole-record test's) coefficients left on the regressors goes out as it
//!   does from the simulations;
//! - `spikes`: samples beyond 6 robust sigma of the 5-point running median are replaced by
//!   that median;
//! - stochastic effects go into the model, which from then on is the user model of the next
//!   round (the first round's fitted baseline when there was none): `quantization`
//!   (rounding), `markov` (a Gauss-Markov term), `white_noise`, `bias_instability`,
//!   `rate_random_walk` (added in quadrature);
//! - except `quantization` named against a fitted baseline: the next rounds fit the
//!   baseline (its noise terms and colour) again on the record, rounding to the quantum, so
//!   that a deterministic candidate still refits them with its signal taken out; the
//!   baseline's own terms may then be named, as against a model, and the first effect that
//!   enters the model makes that round's baseline (and colour) the model;
//! - an effect that enters a fitted baseline (`rate_ramp`'s noise terms, the first
//!   `warmup`, `markov`) brings the N, B, K its candidate was refitted with (`refit_*`), and `markov` without
//!   the baseline's colour when its candidate dropped it (`colour_dropped`);
//! - `dropouts` cannot be undone: it leaves the vocabulary.
//!
//! A record changed under a model that rounds is rounded again to the model's quantum,
//! stochastically (up with probability the fractional part, `reround`): to the nearest
//! count, a slow signal taken out leaves a sawtooth of up to half a quantum.

use super::effects::Effect;
use super::{diagnose, Diagnosis, Options, Rec, TimeInfo};
use crate::sim::{Model, QuantMode};
use anyhow::Result;
use serde::Serialize;
use std::collections::BTreeMap;

/// One round's result.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    /// 1-based.
    pub round: usize,
    /// Named effect (`none` ends the rounds).
    pub effect: String,
    /// Its parameters.
    pub params: Option<BTreeMap<String, f64>>,
    /// 95 % intervals where known (drift effects, markov, sinusoid).
    pub params_ci95: Option<BTreeMap<String, [f64; 2]>>,
    /// Jackknife standard uncertainty where known (scale factor).
    pub params_sigma: Option<BTreeMap<String, f64>>,
    /// Held-out gap before and after, and the shrink.
    pub gap_before: f64,
    /// Held-out gap with the effect.
    pub gap_after: f64,
    /// `1 - gap_after / gap_before`.
    pub shrink: f64,
    /// The baseline's held-out gap per feature group (`gap_before` is the largest): which
    /// features the record departs from the round's model in.
    pub group_gap_before: BTreeMap<String, f64>,
    /// The round's null held-out gap (the model's own simulations scored against each
    /// other): median.
    pub null_gap_median: f64,
    /// Its 95 % quantile.
    pub null_gap_95: f64,
    /// The shrink the named (or best) candidate must beat: the 95 % quantile of the shrink
    /// it gives the model's own simulations ([`super::Candidate::null_shrink_95`]).
    pub null_shrink_95: Option<f64>,
    /// The best candidate of the round, named or not.
    pub best_candidate: Option<String>,
    /// Times (s from the first sample) of the samples a named `spikes` replaced.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub spike_times_s: Vec<f64>,
    /// Why.
    pub decision: String,
    /// How the effect enters the next round.
    pub applied: String,
    /// Every candidate of the round: its fit, held-out shrink, null shrink and why it was
    /// not named (round 1's are also the report's top-level `candidates`).
    pub candidates: Vec<super::Candidate>,
    /// The round's dedicated tests.
    pub tests: Vec<super::evidence::Test>,
}

fn p(params: &Option<BTreeMap<String, f64>>, k: &str) -> f64 {
    params
        .as_ref()
        .and_then(|m| m.get(k).copied())
        .unwrap_or(0.0)
}

/// An effect that enters the model takes the noise terms its candidate was fitted with
/// ([`super::effects::REFIT_KEYS`]: a fitted baseline refitted together with it), so that
/// the next round does not simulate what the first fit absorbed twice; a user model's
/// candidates carry none.
fn take_refit_noise(m: &mut Model, pr: &Option<BTreeMap<String, f64>>) {
    let get = |k: &str| pr.as_ref().and_then(|x| x.get(k).copied());
    let [n_key, b_key, k_key] = super::effects::REFIT_KEYS;
    if let (Some(n), Some(b), Some(k)) = (get(n_key), get(b_key), get(k_key)) {
        m.noise.arw_dps_per_rthz = n;
        m.noise.bias_instability_dps = b;
        m.noise.rrw_dps_per_s_rthz = k;
    }
}

/// The parameters a named effect `e` is applied with: the diagnosis's, but for `markov` the
/// candidate's own terms, as its held-out gap was scored (the reported `gm_*` are the
/// whole-record Whittle fit's, whose B and K are not carried: with the candidate's N, B, K
/// they make a model that was never scored).
fn applied_params(e: Effect, d: &Diagnosis) -> Option<BTreeMap<String, f64>> {
    let own = (e == Effect::Markov)
        .then(|| d.candidates.iter().find(|c| c.effect == e))
        .flatten()
        .and_then(|c| c.params.clone());
    own.or_else(|| d.params.clone())
}

/// Applies a named effect with its parameters `pr` ([`applied_params`]): the record for the
/// next round, the model (if it changed) and what was done, in words. A temperature link or
/// a ramp taken out of the record also adds its regressors to `taken_out`, to be taken out
/// of every later simulation; a ramp adds the slope it took out (`less_ramp`: the record's
/// whole, a user model's own ramp included), and a later link what its refit takes out on
/// time, to `ramp_out_dps_per_s` ([`Outcome::ramp_out_dps_per_s`]).
fn apply(
    e: Effect,
    pr: &Option<BTreeMap<String, f64>>,
    rec: &Rec,
    model: &Model,
    spike_times_s: &mut Vec<f64>,
    taken_out: &mut Option<std::sync::Arc<super::effects::TakenOut>>,
    ramp_out_dps_per_s: &mut f64,
) -> (Rec, Option<Model>, String) {
    let mut r = rec.clone();
    let mut m = model.clone();
    // `r` is a copy: the signals read `rec`'s columns directly.
    let sub = |r: &mut Rec, f: &dyn Fn(usize) -> f64| {
        for (i, v) in r.rate_dps.iter_mut().enumerate() {
            *v -= f(i);
        }
    };
    let t = &rec.t_s;
    let what = match e {
        Effect::RateRamp => {
            take_refit_noise(&mut m, pr);
            let k = p(pr, "rate_ramp_dps_per_s");
            let out = taken_out_with(taken_out.as_deref(), vec![], Some(t));
            // The record has no slope left over its samples: a user model's own ramp (which
            // the drift tests subtract first) goes out with it, and so the model has none.
            let slope = less_ramp(&mut r.rate_dps, t, &out, k);
            *ramp_out_dps_per_s += slope;
            m.noise.rate_ramp_dps_per_s = 0.0;
            *taken_out = Some(std::sync::Arc::new(out));
            format!(
                "subtracted a rate ramp of {:.4} deg/h/h (the named {:.4}, then the fit over all samples of what is left)",
                slope * 3600.0 * 3600.0,
                k * 3600.0 * 3600.0
            )
        }
        Effect::Warmup if m.bias.warmup_dps == 0.0 => {
            take_refit_noise(&mut m, pr);
            m.bias.warmup_dps = p(pr, "warmup_dps");
            m.bias.warmup_tau_s = p(pr, "warmup_tau_s").max(1e-6);
            format!(
                "model's warm-up {:.3} deg/h, tau {:.0} s",
                m.bias.warmup_dps * 3600.0,
                m.bias.warmup_tau_s
            )
        }
        Effect::Warmup => {
            let (a, tau) = (p(pr, "warmup_dps"), p(pr, "warmup_tau_s").max(1e-9));
            sub(&mut r, &|i| a * (-t[i] / tau).exp());
            format!("subtracted {:.3} deg/h exp(-t / {tau:.0} s)", a * 3600.0)
        }
        Effect::Temperature => match temperature_columns(pr, rec) {
            Some((cols, t_ref)) => {
                let (k1, k2) = (p(pr, "bias_dps_per_c"), p(pr, "bias_dps_per_c_per_s"));
                sub(&mut r, &|i| k1 * cols[0][i] + k2 * cols[1][i]);
                let out = taken_out_with(taken_out.as_deref(), cols, None);
                *taken_out = Some(std::sync::Arc::new(out));
                format!(
                    "subtracted {:.4} deg/h/C (temp_c - {t_ref:.2} C) and {:.3} deg/h/(C/s) d temp_c/dt, then the fit over all samples on both of what is left",
                    k1 * 3600.0,
                    k2 * 3600.0
                )
            }
            None => "nothing (no temp_c)".into(),
        },
        Effect::Sinusoid => {
            let (a, f, ph) = (
                p(pr, "sine_amplitude_dps"),
                p(pr, "sine_freq_hz"),
                p(pr, "sine_phase_deg").to_radians(),
            );
            sub(&mut r, &|i| {
                a * (std::f64::consts::TAU * f * t[i] + ph).sin()
            });
            format!("subtracted {:.4} deg/h at {f:.4} Hz", a * 3600.0)
        }
        Effect::ScaleFactor => match &rec.ref_dps {
            Some(rf) => {
                let k = 1e-6 * p(pr, "scale_factor_error_ppm");
                sub(&mut r, &|i| k * rf[i]);
                format!("subtracted {:.0} ppm of the reference rate", k * 1e6)
            }
            None => "nothing (no reference rate)".into(),
        },
        Effect::Spikes => {
            let res = super::effects::running_median_residuals(&rec.rate_dps);
            let s = super::features::robust_sigma(&res);
            let mut count = 0;
            for (j, e) in res.iter().enumerate() {
                if e.abs() > 6.0 * s {
                    r.rate_dps[j + 2] -= e;
                    spike_times_s.extend(rec.t_s.get(j + 2));
                    count += 1;
                }
            }
            format!("replaced {count} samples beyond 6 robust sigma by the running median")
        }
        Effect::Quantization => {
            m.quantization.quantum_dps = p(pr, "quantum_dps");
            m.quantization.mode = QuantMode::Round;
            format!("model rounds to {:.6e} deg/s", m.quantization.quantum_dps)
        }
        Effect::Markov => {
            // `pr`: the candidate's own terms ([`applied_params`]).
            take_refit_noise(&mut m, pr);
            m.noise.gm_sigma_dps = p(pr, "gm_sigma_dps");
            m.noise.gm_tau_s = p(pr, "gm_tau_s").max(1e-6);
            format!(
                "model has a Gauss-Markov term {:.4} deg/h, T {:.3} s",
                m.noise.gm_sigma_dps * 3600.0,
                m.noise.gm_tau_s
            )
        }
        Effect::WhiteNoise => {
            let a = p(pr, "added_arw_dps_per_rthz");
            m.noise.arw_dps_per_rthz = m.noise.arw_dps_per_rthz.hypot(a);
            "model's white noise raised".into()
        }
        Effect::BiasInstability => {
            let a = p(pr, "added_bias_instability_dps");
            m.noise.bias_instability_dps = m.noise.bias_instability_dps.hypot(a);
            "model's bias instability raised".into()
        }
        Effect::RateRandomWalk => {
            let a = p(pr, "added_rrw_dps_per_s_rthz");
            m.noise.rrw_dps_per_s_rthz = m.noise.rrw_dps_per_s_rthz.hypot(a);
            "model's rate random walk raised".into()
        }
        Effect::Dropouts => "left out of the vocabulary (cannot be undone)".into(),
    };
    // What earlier rounds took out (a ramp, a link) stays out of a record this effect
    // changed (a link's regressors, a second warm-up have a slope of their own): the fit
    // over all samples on their regressors again, as every simulation takes its own out;
    // the time column's part counts as ramp taken out. A ramp did this itself
    // (`less_ramp`, with time among the regressors). Only a ramp and a link add to
    // `taken_out`, so it holds the earlier regressors, and after a link its own two: they
    // join the fit, as the named link is the whole-record test's, the
    // simulations take their own least-squares fit out, and so the record does too, as
    // `less_ramp` does for a ramp (real ADIS16405 run 6 x with a link of 20 s100: the
    // named rate-of-change term -987 +- 1080 deg/h/(C/s) was left in the record beside
    // what the fit over all samples takes, a slow wander the simulations lacked, and
    // `rate_random_walk` was named after the link).
    let link = e == Effect::Temperature && rec.temp_c.is_some();
    if e != Effect::RateRamp && (r.rate_dps != rec.rate_dps || link) {
        if let Some(out) = taken_out.as_deref() {
            let beta = out.take_out(t, t, &mut r.rate_dps).unwrap_or_default();
            *ramp_out_dps_per_s += out.slope_dps_per_s(&beta);
        }
    }
    // A record changed under a model that rounds is rounded again to its quantum (the
    // subtraction took its values off the lattice the model reproduces), stochastically.
    let q = m.quantization.quantum_dps;
    if r.rate_dps != rec.rate_dps && m.quantization.mode == QuantMode::Round && q > 0.0 {
        reround(&mut r.rate_dps, q, REROUND_SEED);
    }
    let changed = m != *model;
    (r, changed.then_some(m), what)
}

/// The regressors taken out so far (`before`, if any) and `new` after them, and the time
/// column `t_s` last when given and none is there yet (a second ramp would make the fit
/// singular): what every later simulation takes out of itself.
fn taken_out_with(
    before: Option<&super::effects::TakenOut>,
    new: Vec<Vec<f64>>,
    t_s: Option<&[f64]>,
) -> super::effects::TakenOut {
    let mut cols = before.map(|x| x.cols.clone()).unwrap_or_default();
    let mut time_col = before.and_then(|x| x.time_col);
    cols.extend(new);
    if let Some(t) = t_s.filter(|_| time_col.is_none()) {
        time_col = Some(cols.len());
        cols.push(t.to_vec());
    }
    super::effects::TakenOut { cols, time_col }
}

/// Takes a named ramp of `k_dps_per_s` out of `rate_dps` (at times `t_s`), then what is
/// left of it as every later simulation has its own taken out: the least-squares fit over
/// all samples on `out`'s regressors (time among them, after any taken out before; each
/// centred, so the record keeps the level the named ramp starts from, `mean - k mean(t)`;
/// [`super::effects::TakenOut`]); returns the slope taken out, deg/s per s: `k` and the
/// fit's slope, the record's whole slope beyond the earlier regressors (a user model's own
/// ramp included; `k` alone when the fit is singular). The record's held-out blocks then
/// hold an in-sample residual as the simulations' do. Before, the ramp entered the model
/// at the fit blocks' estimate, and the estimate's error, a slope over the whole record,
/// was a slow wander the simulations lacked (real ADIS16405 run 6 y with a ramp of 30 times
/// its 100-s Allan deviation, `scripts/gap_real_bench.py`: `bias_instability` named after
/// the ramp, which the clean record does not name; now nothing).
fn less_ramp(
    rate_dps: &mut [f64],
    t_s: &[f64],
    out: &super::effects::TakenOut,
    k_dps_per_s: f64,
) -> f64 {
    for (v, t) in rate_dps.iter_mut().zip(t_s) {
        *v -= k_dps_per_s * t;
    }
    let beta = out.take_out(t_s, t_s, rate_dps).unwrap_or_default();
    k_dps_per_s + out.slope_dps_per_s(&beta)
}

/// The temperature link's two regressors on `rec`'s samples, as [`apply`] subtracts them:
/// `temp_c - reference` and the 10-s windows' rate of change; and the reference, deg C
/// (the fit's, else the record's mean temperature).
fn temperature_columns(
    pr: &Option<BTreeMap<String, f64>>,
    rec: &Rec,
) -> Option<(Vec<Vec<f64>>, f64)> {
    let tc = rec.temp_c.as_ref()?;
    let t_total = rec.t_s.last().copied().unwrap_or(0.0) + rec.dt_s;
    let w = super::drift::Windows::new(&rec.t_s, &rec.rate_dps, Some(tc), t_total);
    let t_ref = pr
        .as_ref()
        .and_then(|m| m.get("reference_c").copied())
        .unwrap_or_else(|| super::features::mean(tc));
    let dtw = w.temp.map(|(_, d)| d).unwrap_or_default();
    let c1 = tc.iter().map(|x| x - t_ref).collect();
    let c2 = (0..rec.t_s.len())
        .map(|i| {
            let k = ((rec.t_s[i] / w.w_s) as usize).min(dtw.len().saturating_sub(1));
            dtw.get(k).copied().unwrap_or(0.0)
        })
        .collect();
    Some((vec![c1, c2], t_ref))
}

/// Seed of [`reround`]'s draws (fixed: the rounds are reproducible).
const REROUND_SEED: u64 = 0x0D17_4E5D;

/// Rounds `values` to the lattice of `quantum` stochastically: up with probability the
/// fractional part (a value already on the lattice, within 1e-9 of a quantum, stays).
/// Why not to the nearest: the record was on the lattice, so after a slow signal `x(t)` is
/// subtracted every sample's fractional part is `frac(-x(t))`, whatever the sensor's noise,
/// and the nearest count adds the same rounding error to every sample of a stretch: a
/// sawtooth in `x` of up to half a quantum, a slow wander the model's simulations (noise
/// rounded where it dithers the quantum) do not have. Real ADIS16405 records (quantum 0.05
/// deg/s = 180 deg/h) with a temperature link of about 0.85 deg/s added: even the true link
/// taken out and rounded to the nearest count, the next round named `bias_instability`
/// where the clean record names `rate_random_walk`. Rounded stochastically, the error has
/// mean 0 at every sample and a variance of at most a quarter quantum squared (on the ADIS
/// 0.3 % of its noise).
fn reround(values: &mut [f64], quantum: f64, seed: u64) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    for v in values.iter_mut() {
        let u = *v / quantum;
        let f = u.floor();
        let frac = u - f;
        let draw: f64 = rng.random();
        let up = if frac < 1e-9 {
            false
        } else if frac > 1.0 - 1e-9 {
            true
        } else {
            draw < frac
        };
        *v = (f + if up { 1.0 } else { 0.0 }) * quantum;
    }
}

/// A group of the held-out features whose gap stays above its own null 95 % quantile once
/// the rounds end: what no named effect of the vocabulary explained.
#[derive(Debug, Clone, Serialize)]
pub struct Unexplained {
    /// The group (`adev`, `psd`, `dist`, `time`, `drift`; docs/gap.md).
    pub group: String,
    /// Its held-out gap (mean z^2 of its features) in the last round's diagnosis.
    pub gap: f64,
    /// The 95 % quantile of the same group's gap among the model's own simulations.
    pub null_gap_95: f64,
    /// Where and how far, in plain units (from the last round's plain summary).
    pub what: String,
}

/// The rounds' outcome.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The first round's diagnosis (the record against the user's or the fitted model).
    pub first: Diagnosis,
    /// Every round.
    pub rounds: Vec<Round>,
    /// The last round's diagnosis's held-out gap and its null 95 % quantile.
    pub final_gap: f64,
    /// See `final_gap`.
    pub final_null_gap_95: f64,
    /// The groups still above their null 95 % after the last round (empty when the gap
    /// closed).
    pub unexplained: Vec<Unexplained>,
    /// Why the rounds stopped, in words.
    pub stopped: String,
    /// The model the last round simulated: the user's or the first round's fitted
    /// baseline, with every named effect that enters the model added (module docs); the
    /// effects taken out of the record are not in it (`gap --save-gyro` adds
    /// [`Outcome::ramp_out_dps_per_s`] back).
    pub model: Model,
    /// The ramp a named `rate_ramp` took out of the record, deg/s per s: the named slope
    /// and the fit over all samples after it (the record's whole slope, a user model's own
    /// ramp included), and what a later link's refit took out on time; 0 when none was
    /// named. ASSUMED: time and the links' regressors are not nearly collinear (a
    /// temperature that rises steadily over the whole record): there the split between
    /// them, and so this slope, is not determined, though what the record loses is.
    pub ramp_out_dps_per_s: f64,
}

/// The groups of `d` whose held-out gap exceeds their null 95 % quantile, largest ratio
/// first, each with the plain words for it.
pub fn unexplained_groups(d: &Diagnosis) -> Vec<Unexplained> {
    let mut out: Vec<Unexplained> = d
        .group_gap_before
        .iter()
        .filter_map(|(g, &gap)| {
            let nulls = d.null_group_gaps.get(g)?;
            let q95 = super::features::quantile(nulls, 0.95);
            (gap.is_finite() && gap > q95).then(|| Unexplained {
                group: g.clone(),
                gap,
                null_gap_95: q95,
                what: group_words(g, d),
            })
        })
        .collect();
    out.sort_by(|a, b| {
        (b.gap / b.null_gap_95.max(1e-12)).total_cmp(&(a.gap / a.null_gap_95.max(1e-12)))
    });
    out
}

/// A group's departure in words, from the diagnosis's plain summary.
fn group_words(group: &str, d: &Diagnosis) -> String {
    let p = &d.plain;
    let dep = |x: &Option<super::plain::Departure>, what: &str, unit: &str| {
        x.as_ref().map_or(String::new(), |x| {
            format!(
                "{what} {:+.0} % at {:.3} {unit} (median {:.0} % over the curve)",
                x.percent, x.at, x.median_abs_percent
            )
        })
    };
    match group {
        "adev" => dep(&p.adev, "Allan deviation", "s"),
        "psd" => dep(&p.psd, "PSD", "Hz"),
        "dist" => {
            if p.distribution.is_empty() {
                "the value distribution".into()
            } else {
                p.distribution.join("; ")
            }
        }
        "time" => p.mean_offset_dph.map_or(String::new(), |(o, [a, b])| {
            format!("a window mean {o:+.1} deg/h off the model at {a:.0}-{b:.0} s")
        }),
        _ => "slow drift of the window means".into(),
    }
}

/// The rounds of the diagnosis: each named effect is applied (above) and leaves the
/// vocabulary, so no effect is named twice; the rounds stop at `none` (the gap closed, or
/// nothing left in the vocabulary lowers it) or after `n`. `progress` is told when each
/// round starts.
pub fn run(
    rec: &Rec,
    time: TimeInfo,
    model: Option<&Model>,
    o: &Options,
    n: usize,
    mut progress: impl FnMut(usize),
) -> Result<Outcome> {
    let mut rec = rec.clone();
    let mut model: Option<Model> = model.cloned();
    let mut o = o.clone();
    let mut first = None;
    let mut last = None;
    let mut rounds = Vec::new();
    let mut ramp_out_dps_per_s = 0.0;
    let n = n.max(1);
    for k in 1..=n {
        progress(k);
        let d = diagnose(&rec, time.clone(), model.as_ref(), &o)?;
        // While the baseline is fitted to the record, so is its colour (a record that lost
        // a line or a temperature link is fitted again, against its refitted terms); the
        // colour of the round whose baseline becomes the model shapes it in every later
        // round; a `markov` candidate that found the colour to be the baseline's misfit of
        // its hump (`colour_dropped`) leaves none.
        let colour_now = d
            .colour
            .clone()
            .filter(|_| p(&d.params, super::effects::COLOUR_DROPPED) == 0.0)
            .map(std::sync::Arc::new);
        let marginal_now = d.marginal.clone().map(std::sync::Arc::new);
        let named = Effect::parse_list(&d.effect)
            .ok()
            .and_then(|v| v.first().copied());
        let mut round = Round {
            round: k,
            effect: d.effect.clone(),
            params: d.params.clone(),
            params_ci95: d.params_ci95.clone(),
            params_sigma: d.params_sigma.clone(),
            gap_before: d.gap_before,
            gap_after: d.gap_after,
            shrink: d.shrink,
            group_gap_before: d.group_gap_before.clone(),
            null_gap_median: d.null_gap_median,
            null_gap_95: d.null_gap_95,
            null_shrink_95: d
                .best_candidate
                .and_then(|b| d.candidates.iter().find(|c| c.effect == b))
                .and_then(|c| c.null_shrink_95),
            best_candidate: d.best_candidate.map(|e| e.name().to_string()),
            spike_times_s: Vec::new(),
            decision: d.decision.clone(),
            applied: String::new(),
            candidates: d.candidates.clone(),
            tests: d.tests.clone(),
        };
        if let Some(e) = named.filter(|_| k < n) {
            let base = model.clone().unwrap_or_else(|| d.baseline.clone());
            let spikes = &mut round.spike_times_s;
            let (r2, m2, what) = apply(
                e,
                &applied_params(e, &d),
                &rec,
                &base,
                spikes,
                &mut o.taken_out,
                &mut ramp_out_dps_per_s,
            );
            rec = r2;
            match m2 {
                // Quantization named against a fitted baseline: the next round fits the
                // baseline again, rounding to the quantum, so that its candidates still
                // refit the noise terms (real ADIS16405 run 4 x with a line: the first fit
                // took the line for flicker, B 0.145 deg/s against 0.012 without it, and a
                // line added to that frozen flicker did not lower the gap).
                Some(m2) if e == Effect::Quantization && model.is_none() => {
                    o.fitted_quantum_dps = Some(m2.quantization.quantum_dps);
                }
                Some(m2) => {
                    if model.is_none() && matches!(o.colour, super::ColourMode::Fit) {
                        o.colour = super::ColourMode::Fixed(colour_now, marginal_now);
                    }
                    model = Some(m2);
                }
                None => {}
            }
            // Named once: it leaves the vocabulary (a second line, warm-up or Gauss-Markov
            // term is not looked for).
            o.effects.retain(|x| *x != e);
            round.applied = what;
        }
        rounds.push(round);
        let stop = named.is_none() || o.effects.is_empty();
        if first.is_none() {
            first = Some(d);
        } else {
            last = Some(d);
        }
        if stop {
            break;
        }
    }
    let first = first.ok_or_else(|| anyhow::anyhow!("no round ran"))?;
    let end = last.as_ref().unwrap_or(&first);
    let k = rounds.len();
    let stopped = match rounds.last().map(|r| r.effect.as_str()) {
        Some("none") if end.gap_before <= end.null_gap_95 => format!(
            "round {k} named none: the held-out gap {:.3} is within the null's 95 % ({:.3})",
            end.gap_before, end.null_gap_95
        ),
        Some("none") => format!(
            "round {k} named none: nothing in the vocabulary explains the rest (no effect left lowers the held-out gap {:.3} by more than chance: the null's spread and its null shrink; the null's 95 % is {:.3})",
            end.gap_before, end.null_gap_95
        ),
        _ if o.effects.is_empty() => format!("round {k}: every effect of the vocabulary named"),
        _ => format!(
            "the cap of {n} rounds reached (--rounds); the last round's effect is not applied and its diagnosis is before it"
        ),
    };
    // Without a model of its own, the last round's fitted baseline (rounding to a quantum
    // named earlier).
    let model = model.unwrap_or_else(|| end.baseline.clone());
    Ok(Outcome {
        model,
        ramp_out_dps_per_s,
        final_gap: end.gap_after,
        final_null_gap_95: end.null_gap_95,
        unexplained: unexplained_groups(end),
        stopped,
        rounds,
        first,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ramp taken out with a named slope 20 % short, after a regressor taken out before (a
    /// temperature link's): the record keeps no slope and none of the earlier regressor over
    /// all samples (where the named slope's subtraction alone leaves the 20 %), keeps the
    /// level the named ramp starts from, and the slope returned is the record's (1e-4 deg/s
    /// per s, within its noise's 1e-7); a second ramp adds no second time column (the fit
    /// would be singular).
    #[test]
    fn a_taken_out_ramp_leaves_no_slope_over_all_samples() {
        let n = 6_000;
        let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let earlier: Vec<f64> = t_s.iter().map(|t| (t / 97.0).sin()).collect();
        let rate: Vec<f64> = (0..n)
            .map(|i| {
                2.0 + 1e-4 * t_s[i]
                    + 0.3 * earlier[i]
                    + 0.01 * (((i * 7919) % 101) as f64 / 50.0 - 1.0)
            })
            .collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
        let before = super::super::effects::TakenOut {
            cols: vec![earlier.clone()],
            time_col: None,
        };
        let out = taken_out_with(Some(&before), vec![], Some(&t_s));
        assert_eq!(out.cols, vec![earlier.clone(), t_s.clone()]);
        assert_eq!(out.time_col, Some(1));
        // The named slope 20 % short: the estimate's subtraction alone leaves the 20 %.
        let k = 0.8e-4;
        let only_estimate: Vec<f64> = (0..n)
            .map(|i| rate[i] - 0.3 * earlier[i] - k * t_s[i])
            .collect();
        assert!((coef(&t_s, &only_estimate) - 0.2e-4).abs() < 0.02e-4);
        let mut less = rate.clone();
        let slope = less_ramp(&mut less, &t_s, &out, k);
        assert!((slope - 1e-4).abs() < 1e-7, "{slope}");
        assert!(coef(&t_s, &less).abs() < 1e-12, "{}", coef(&t_s, &less));
        assert!(
            coef(&earlier, &less).abs() < 1e-9,
            "{}",
            coef(&earlier, &less)
        );
        // The level the named ramp starts from.
        let level = mean(&rate) - k * mean(&t_s);
        assert!((mean(&less) - level).abs() < 1e-9, "{}", mean(&less));
        let again = taken_out_with(Some(&out), vec![], Some(&t_s));
        assert_eq!(again.cols.len(), 2);
        assert_eq!(again.time_col, Some(1));
        let mut twice = less.clone();
        assert!(less_ramp(&mut twice, &t_s, &again, 0.0).abs() < 1e-12);
    }

    /// The least-squares slope of `y` on `x` (with an intercept).
    fn coef(x: &[f64], y: &[f64]) -> f64 {
        let m = x.iter().sum::<f64>() / x.len() as f64;
        let xc: Vec<f64> = x.iter().map(|v| v - m).collect();
        xc.iter().zip(y).map(|(a, b)| a * b).sum::<f64>() / xc.iter().map(|a| a * a).sum::<f64>()
    }

    /// An effect's parameters from `(key, value)` pairs.
    fn params(kv: &[(&str, f64)]) -> Option<BTreeMap<String, f64>> {
        Some(kv.iter().map(|&(k, v)| (k.to_string(), v)).collect())
    }

    /// A link named after a ramp (`apply` twice, no quantum), its coefficients 20 % off:
    /// the link's regressors have a slope of their own, so its subtraction gives the record
    /// a slope again, which the fit over all samples on time and the link's regressors
    /// takes out with the link's leftover; the record ends with no slope and no projection
    /// on the link's regressors, and the ramp counted is the record's least-squares slope
    /// given the link's regressors (as a ramp named after the link counts it).
    #[test]
    fn a_link_after_a_ramp_keeps_the_ramp_out_and_counted() {
        let n = 20_000;
        let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let temp: Vec<f64> = t_s
            .iter()
            .map(|t| 30.0 + 8.0 * (1.0 - (-t / 600.0).exp()))
            .collect();
        let rate: Vec<f64> = (0..n)
            .map(|i| {
                0.2 + 2e-5 * t_s[i]
                    + 0.004 * (temp[i] - 35.0)
                    + 0.01 * (((i * 7919) % 101) as f64 / 50.0 - 1.0)
            })
            .collect();
        let rec = Rec {
            name: "ramp-link".into(),
            t_s: t_s.clone(),
            rate_dps: rate.clone(),
            temp_c: Some(temp),
            ref_dps: None,
            dt_s: 0.1,
        };
        let model = Model::default();
        let (mut spikes, mut taken_out, mut ramp_out) = (Vec::new(), None, 0.0);
        // The ramp named first absorbs part of the link (the temperature rises).
        let ramp = params(&[("rate_ramp_dps_per_s", 3e-5)]);
        let (r1, _, _) = apply(
            Effect::RateRamp,
            &ramp,
            &rec,
            &model,
            &mut spikes,
            &mut taken_out,
            &mut ramp_out,
        );
        assert!(coef(&t_s, &r1.rate_dps).abs() < 1e-12);
        assert!((ramp_out - coef(&t_s, &rate)).abs() < 1e-12, "{ramp_out}");
        let link = params(&[
            ("bias_dps_per_c", 0.0032),
            ("bias_dps_per_c_per_s", 0.0),
            ("reference_c", 35.0),
        ]);
        let (r2, _, _) = apply(
            Effect::Temperature,
            &link,
            &r1,
            &model,
            &mut spikes,
            &mut taken_out,
            &mut ramp_out,
        );
        let out = taken_out.expect("taken out");
        assert_eq!(out.cols.len(), 3);
        assert_eq!(out.time_col, Some(0));
        // Nothing left on any regressor taken out: time, the link's two.
        let mut again = r2.rate_dps.clone();
        let left = out.take_out(&t_s, &t_s, &mut again).expect("fit");
        assert!(left.iter().all(|b| b.abs() < 1e-12), "{left:?}");
        // The ramp counted: the record's slope given the link's regressors (the true link
        // is 0.004 deg/s/C, its rate-of-change term 0).
        let mut whole = rate.clone();
        let beta = out.take_out(&t_s, &t_s, &mut whole).expect("fit");
        assert!((beta[0] - 2e-5).abs() < 1e-7, "{beta:?}");
        assert!((beta[1] - 0.004).abs() < 1e-5, "{beta:?}");
        assert!(
            (ramp_out - beta[0]).abs() < 1e-12,
            "{ramp_out} vs {}",
            beta[0]
        );
    }

    /// A constant regressor (a link's rate of change on a record whose temperature does not
    /// move) is left out of the fit: the others are still taken out, its coefficient 0.
    #[test]
    fn a_constant_regressor_does_not_stop_the_fit() {
        let t_s: Vec<f64> = (0..1000).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t_s.iter().map(|t| 1.0 + 0.02 * t).collect();
        let out = super::super::effects::TakenOut {
            cols: vec![t_s.clone(), vec![3.0; t_s.len()]],
            time_col: Some(0),
        };
        let mut less = y.clone();
        let beta = out.take_out(&t_s, &t_s, &mut less).expect("fit");
        assert!((beta[0] - 0.02).abs() < 1e-12 && beta[1] == 0.0, "{beta:?}");
        assert!(coef(&t_s, &less).abs() < 1e-12);
    }

    /// A link named alone with its coefficients 20 % short (`apply`, no quantum): the
    /// record is left with no projection on the link's two regressors (the fit over all
    /// samples takes the leftover out, as every later simulation takes its own fit out),
    /// where the named coefficients alone leave the 20 %; no ramp is counted.
    #[test]
    fn a_named_link_leaves_nothing_on_its_regressors() {
        let n = 20_000;
        let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let temp: Vec<f64> = t_s
            .iter()
            .map(|t| 30.0 + 1.5 * (std::f64::consts::TAU * t / 900.0).sin())
            .collect();
        let rate: Vec<f64> = (0..n)
            .map(|i| {
                0.2 + 0.004 * (temp[i] - 30.0) + 0.01 * (((i * 7919) % 101) as f64 / 50.0 - 1.0)
            })
            .collect();
        let rec = Rec {
            name: "link".into(),
            t_s: t_s.clone(),
            rate_dps: rate.clone(),
            temp_c: Some(temp.clone()),
            ref_dps: None,
            dt_s: 0.1,
        };
        let link = params(&[
            ("bias_dps_per_c", 0.0032),
            ("bias_dps_per_c_per_s", 0.0),
            ("reference_c", 30.0),
        ]);
        let only_named: Vec<f64> = (0..n)
            .map(|i| rate[i] - 0.0032 * (temp[i] - 30.0))
            .collect();
        assert!((coef(&temp, &only_named) - 0.0008).abs() < 2e-5);
        let (mut spikes, mut taken_out, mut ramp_out) = (Vec::new(), None, 0.0);
        let (r, _, _) = apply(
            Effect::Temperature,
            &link,
            &rec,
            &Model::default(),
            &mut spikes,
            &mut taken_out,
            &mut ramp_out,
        );
        assert!(
            coef(&temp, &r.rate_dps).abs() < 1e-12,
            "{}",
            coef(&temp, &r.rate_dps)
        );
        let out = taken_out.expect("taken out");
        assert_eq!(out.cols.len(), 2);
        let mut again = r.rate_dps.clone();
        let left = out.take_out(&t_s, &t_s, &mut again).expect("fit");
        assert!(left.iter().all(|b| b.abs() < 1e-12), "{left:?}");
        assert_eq!(ramp_out, 0.0);
    }

    /// A second warm-up subtracted from the record after a ramp was taken out (`apply`
    /// twice, no quantum): the exponential has a slope of its own, which the ramp's fit takes
    /// out again and counts; the record ends with no slope over all samples, and the ramp
    /// counted is the slope of the record less that warm-up.
    #[test]
    fn an_effect_subtracted_after_a_ramp_keeps_the_ramp_out() {
        let n = 20_000;
        let t_s: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let warm = |t: f64| 0.05 * (-t / 300.0).exp();
        let rate: Vec<f64> = (0..n)
            .map(|i| {
                0.2 + 2e-5 * t_s[i] + warm(t_s[i]) + 0.01 * (((i * 7919) % 101) as f64 / 50.0 - 1.0)
            })
            .collect();
        let rec = Rec {
            name: "ramp-warm-up".into(),
            t_s: t_s.clone(),
            rate_dps: rate.clone(),
            temp_c: None,
            ref_dps: None,
            dt_s: 0.1,
        };
        // The model has a warm-up already: a second one is subtracted from the record.
        let mut model = Model::default();
        model.bias.warmup_dps = 0.01;
        let (mut spikes, mut taken_out, mut ramp_out) = (Vec::new(), None, 0.0);
        let (r1, _, _) = apply(
            Effect::RateRamp,
            &params(&[("rate_ramp_dps_per_s", 0.0)]),
            &rec,
            &model,
            &mut spikes,
            &mut taken_out,
            &mut ramp_out,
        );
        let (r2, _, what) = apply(
            Effect::Warmup,
            &params(&[("warmup_dps", 0.05), ("warmup_tau_s", 300.0)]),
            &r1,
            &model,
            &mut spikes,
            &mut taken_out,
            &mut ramp_out,
        );
        assert!(what.starts_with("subtracted"), "{what}");
        assert!(coef(&t_s, &r2.rate_dps).abs() < 1e-12);
        let less_warm: Vec<f64> = rate.iter().zip(&t_s).map(|(v, &t)| v - warm(t)).collect();
        let want = coef(&t_s, &less_warm);
        assert!((want - 2e-5).abs() < 1e-7, "{want}");
        assert!((ramp_out - want).abs() < 1e-12, "{ramp_out} vs {want}");
    }

    /// A record on a lattice of 0.05 deg/s with a slow signal of 20 quanta taken out: the
    /// stochastic re-rounding's error averages to nothing over every 10-s stretch (no
    /// sawtooth in the signal), where rounding to the nearest count leaves a stretch's mean
    /// error above 0.3 quantum (up to half); values already on the lattice stay as they are.
    #[test]
    fn re_rounding_leaves_no_sawtooth_of_the_signal() {
        let q = 0.05;
        let n = 100_000; // 1000 s at 100 Hz
        let on_lattice: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 * q).collect();
        let mut same = on_lattice.clone();
        reround(&mut same, q, 1);
        assert_eq!(same, on_lattice);
        let signal = |i: usize| 20.0 * q * i as f64 / n as f64;
        let less: Vec<f64> = (0..n).map(|i| on_lattice[i] - signal(i)).collect();
        let mut stochastic = less.clone();
        reround(&mut stochastic, q, 7);
        let nearest: Vec<f64> = less.iter().map(|v| (v / q).round() * q).collect();
        let worst_stretch_error = |out: &[f64]| -> f64 {
            out.chunks(1000)
                .zip(less.chunks(1000))
                .map(|(o, l)| {
                    (o.iter().zip(l).map(|(a, b)| a - b).sum::<f64>() / o.len() as f64).abs()
                })
                .fold(0.0, f64::max)
        };
        // 1000 samples of variance <= q^2 / 4: the mean's standard deviation <= 0.016 q.
        assert!(worst_stretch_error(&stochastic) < 0.07 * q);
        assert!(worst_stretch_error(&nearest) > 0.3 * q);
        for v in &stochastic {
            assert!(((v / q) - (v / q).round()).abs() < 1e-9);
        }
    }
}
