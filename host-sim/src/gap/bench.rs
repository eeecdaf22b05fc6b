//! Benchmark of the diagnosis on simulated records whose extra effect is withheld.
//!
//! Every record: the benchmark baseline (ARW 4 deg/h/sqrt(Hz), B 1.5 deg/h, K 0.5
//! deg/h/sqrt(h): the E-Core 2000 preset's stochastic terms) with a random temperature
//! profile (`temp_c` column, no effect on the rate unless the effect is `temperature`) and a
//! random two-sine turntable motion (`true_rate_dps` reference column), plus ONE extra effect
//! with random parameters (or none). The diagnosis gets the baseline model (`--gyro`) and the
//! record, never the effect.

use super::effects::{Effect, ALL};
use super::{diagnose, regularise, Options, Rec};
use crate::sim::{Model, Simulator};
use anyhow::Result;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// What "right effect named" counts, as the output states it.
pub const RIGHT_DEFINITION: &str =
    "the confusion matrix's diagonal over all its records, `none` included";

/// Benchmark options.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Records per class (each effect and `none`).
    pub per_effect: usize,
    /// Simulations per model in each diagnosis.
    pub seeds: usize,
    /// Record length, s.
    pub duration_s: f64,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// First record seed.
    pub first_seed: u64,
    /// Worker threads.
    pub jobs: usize,
    /// Classes (None = no extra effect).
    pub classes: Vec<Option<Effect>>,
}

impl Default for BenchOptions {
    fn default() -> Self {
        let mut classes: Vec<Option<Effect>> = vec![None];
        classes.extend(ALL.iter().map(|&e| Some(e)));
        Self {
            per_effect: 8,
            seeds: 12,
            duration_s: 1800.0,
            rate_hz: 100.0,
            first_seed: 1,
            jobs: 1,
            classes,
        }
    }
}

/// One benchmark record's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRecord {
    /// Record seed.
    pub seed: u64,
    /// The withheld effect (`none`).
    pub truth: String,
    /// Its parameters, unit in the key.
    pub truth_params: BTreeMap<String, f64>,
    /// What the diagnosis named.
    pub diagnosed: String,
    /// Its best candidate even when not significant.
    pub best_candidate: Option<Effect>,
    /// Held-out gap before.
    pub gap_before: f64,
    /// 95 % quantile of the null gaps.
    pub null_gap_95: f64,
    /// Median of the null gaps.
    pub null_gap_median: f64,
    /// Held-out gap after the truth's effect was fitted (null for `none`).
    pub gap_after_true_effect: Option<f64>,
    /// Held-out shrink of the named effect.
    pub shrink: f64,
    /// Held-out shrink of the true effect's candidate.
    pub shrink_true_effect: Option<f64>,
    /// Every candidate (fitted parameters, held-out gap, exclusions).
    pub candidates: Vec<super::Candidate>,
}

/// Per-class summary.
#[derive(Debug, Clone, Serialize)]
pub struct ClassSummary {
    /// Records.
    pub records: usize,
    /// Named correctly.
    pub correct: usize,
    /// Median held-out shrink of the true effect's candidate (none: of the named effect).
    pub median_shrink: f64,
}

/// The benchmark report.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// Options in words.
    pub setup: String,
    /// Every record.
    pub records: Vec<BenchRecord>,
    /// `confusion[truth][diagnosed]` = count.
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// Per class.
    pub classes: BTreeMap<String, ClassSummary>,
    /// Records whose named effect is the withheld one (`none` for a record without one):
    /// the confusion matrix's diagonal.
    pub right: usize,
    /// Every record: the matrix's total.
    pub total: usize,
    /// Right effect named: `right / total` (the diagonal over every record, `none`
    /// included; [`RIGHT_DEFINITION`]).
    pub right_rate: f64,
    /// Records without an effect that were flagged.
    pub none_false_rate: f64,
    /// Median shrink of the true effect over records with an effect.
    pub median_shrink: f64,
    /// Goals: right >= 0.9, none false <= 0.1, median shrink >= 0.7.
    pub goals_met: bool,
    /// Wall time, s.
    pub seconds: f64,
}

/// The benchmark baseline model at `rate_hz`.
pub fn baseline_model(rate_hz: f64) -> Model {
    let mut m = Model {
        sample_rate_hz: Some(rate_hz),
        ..Default::default()
    };
    m.noise.arw_dps_per_rthz = 0.001_111_11;
    m.noise.bias_instability_dps = 0.000_416_667;
    m.noise.flicker_tau_min_s = (2.5 / rate_hz).max(1.0);
    m.noise.flicker_tau_max_s = 1e6;
    m.noise.rrw_dps_per_s_rthz = 2.31e-6;
    m
}

fn lu(rng: &mut Pcg64Mcg, a: f64, b: f64) -> f64 {
    (a.ln() + rng.random::<f64>() * (b.ln() - a.ln())).exp()
}

fn u(rng: &mut Pcg64Mcg, a: f64, b: f64) -> f64 {
    a + rng.random::<f64>() * (b - a)
}

fn sign(rng: &mut Pcg64Mcg) -> f64 {
    if rng.random::<bool>() {
        1.0
    } else {
        -1.0
    }
}

/// A record of the baseline plus `effect` (random parameters from `seed`).
pub fn make_record(
    effect: Option<Effect>,
    seed: u64,
    duration_s: f64,
    rate_hz: f64,
) -> Result<(Rec, super::TimeInfo, BTreeMap<String, f64>)> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0xA5A5);
    let mut m = baseline_model(rate_hz);
    let dt = 1.0 / rate_hz;
    let sigma_white = m.noise.arw_dps_per_rthz / dt.sqrt();
    let b = m.noise.bias_instability_dps;
    let te = &mut m.temperature;
    te.initial_c = u(&mut rng, 15.0, 30.0);
    te.warmup_rise_c = u(&mut rng, 2.0, 8.0);
    te.warmup_tau_s = u(&mut rng, 300.0, 900.0);
    te.cycle_amplitude_c = u(&mut rng, 0.5, 2.0);
    te.cycle_period_s = u(&mut rng, 400.0, 1200.0);
    let motion = [
        (
            u(&mut rng, 5.0, 50.0),
            lu(&mut rng, 0.005, 0.05),
            u(&mut rng, 0.0, 6.3),
        ),
        (
            u(&mut rng, 2.0, 20.0),
            lu(&mut rng, 0.05, 0.2),
            u(&mut rng, 0.0, 6.3),
        ),
    ];
    let mut p = BTreeMap::new();
    let mut quantum = 0.0;
    let mut ppm = 0.0;
    match effect {
        None => {}
        Some(Effect::Quantization) => {
            quantum = lu(&mut rng, 0.05, 1.0) * sigma_white;
            p.insert("quantum_dps".into(), quantum);
        }
        Some(Effect::WhiteNoise) => {
            let r = lu(&mut rng, 1.3, 3.0);
            m.noise.arw_dps_per_rthz *= r;
            p.insert("arw_ratio".into(), r);
        }
        Some(Effect::BiasInstability) => {
            let r = lu(&mut rng, 2.5, 8.0);
            m.noise.bias_instability_dps *= r;
            p.insert("bias_instability_ratio".into(), r);
        }
        Some(Effect::RateRandomWalk) => {
            let r = lu(&mut rng, 25.0, 80.0);
            m.noise.rrw_dps_per_s_rthz *= r;
            p.insert("rrw_ratio".into(), r);
        }
        Some(Effect::RateRamp) => {
            let r = sign(&mut rng) * lu(&mut rng, 15.0, 100.0) / 3600.0 / 3600.0;
            m.noise.rate_ramp_dps_per_s = r;
            p.insert("rate_ramp_dps_per_s".into(), r);
        }
        Some(Effect::Markov) => {
            m.noise.gm_sigma_dps = lu(&mut rng, 3.0, 15.0) * b;
            m.noise.gm_tau_s = lu(&mut rng, 5.0, 100.0);
            p.insert("gm_sigma_dps".into(), m.noise.gm_sigma_dps);
            p.insert("gm_tau_s".into(), m.noise.gm_tau_s);
        }
        Some(Effect::Sinusoid) => {
            m.noise.sine_amplitude_dps = lu(&mut rng, 0.1, 1.0) * sigma_white;
            m.noise.sine_freq_hz = lu(&mut rng, 0.02, rate_hz / 4.0);
            m.noise.sine_phase_deg = u(&mut rng, 0.0, 360.0);
            p.insert("sine_amplitude_dps".into(), m.noise.sine_amplitude_dps);
            p.insert("sine_freq_hz".into(), m.noise.sine_freq_hz);
        }
        Some(Effect::Temperature) => {
            let k = sign(&mut rng) * lu(&mut rng, 8.0, 60.0) * b / 5.0;
            m.temperature.bias_dps_per_c = k;
            p.insert("bias_dps_per_c".into(), k);
        }
        Some(Effect::Warmup) => {
            m.bias.warmup_dps = sign(&mut rng) * lu(&mut rng, 10.0, 60.0) * b;
            m.bias.warmup_tau_s = lu(&mut rng, 150.0, 600.0);
            p.insert("warmup_dps".into(), m.bias.warmup_dps);
            p.insert("warmup_tau_s".into(), m.bias.warmup_tau_s);
        }
        Some(Effect::Spikes) => {
            m.faults.spike_probability = lu(&mut rng, 1e-4, 1e-3);
            m.faults.spike_amplitude_dps = lu(&mut rng, 8.0, 40.0) * sigma_white;
            p.insert("spike_probability".into(), m.faults.spike_probability);
            p.insert("spike_amplitude_dps".into(), m.faults.spike_amplitude_dps);
        }
        Some(Effect::Dropouts) => {
            m.faults.drop_probability = lu(&mut rng, 1e-3, 2e-2);
            p.insert("drop_probability".into(), m.faults.drop_probability);
        }
        Some(Effect::ScaleFactor) => {
            ppm = sign(&mut rng) * lu(&mut rng, 200.0, 3000.0);
            p.insert("scale_factor_error_ppm".into(), ppm);
        }
    }
    let mut sim = Simulator::new(&m, seed, rate_hz)?;
    let n = (duration_s * rate_hz) as usize;
    let (mut t, mut y, mut tc, mut rf) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    loop {
        let s = sim.next_sample();
        if s.t_s >= duration_s {
            break;
        }
        let r: f64 = motion
            .iter()
            .map(|(a, f, ph)| a * (std::f64::consts::TAU * f * s.t_s + ph).sin())
            .sum();
        let mut v = s.rate_dps + r * (1.0 + 1e-6 * ppm);
        if quantum > 0.0 {
            v = (v / quantum).round() * quantum;
        }
        t.push(s.t_s);
        y.push(v);
        tc.push(s.temp_c);
        rf.push(r);
    }
    let name = format!(
        "bench seed {seed} ({})",
        effect.map_or("none", Effect::name)
    );
    let (rec, info) = regularise(name, t, y, Some(tc), Some(rf))?;
    Ok((rec, info, p))
}

/// Runs the benchmark.
pub fn run(o: &BenchOptions, progress: &(dyn Fn(&BenchRecord) + Sync)) -> Result<BenchReport> {
    let start = std::time::Instant::now();
    let jobs: Vec<(Option<Effect>, u64)> = o
        .classes
        .iter()
        .enumerate()
        .flat_map(|(ci, &c)| {
            (0..o.per_effect).map(move |k| (c, o.first_seed + (ci * 1000 + k) as u64))
        })
        .collect();
    let base = baseline_model(o.rate_hz);
    let dopt = Options {
        seeds: o.seeds,
        task: false,
        ..Options::default()
    };
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<Result<BenchRecord>>>> =
        Mutex::new((0..jobs.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..o.jobs.max(1) {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(&(effect, seed)) = jobs.get(i) else {
                    break;
                };
                let r = one(effect, seed, o, &base, &dopt);
                if let Ok(rec) = &r {
                    progress(rec);
                }
                if let Ok(mut v) = out.lock() {
                    v[i] = Some(r);
                }
            });
        }
    });
    let results = out
        .into_inner()
        .map_err(|_| anyhow::anyhow!("gap-bench: a worker panicked"))?;
    let mut records = Vec::new();
    for r in results {
        match r {
            Some(r) => records.push(r?),
            None => anyhow::bail!("gap-bench: a record was not run"),
        }
    }
    Ok(summarise(records, o, start.elapsed().as_secs_f64()))
}

fn one(
    effect: Option<Effect>,
    seed: u64,
    o: &BenchOptions,
    base: &Model,
    dopt: &Options,
) -> Result<BenchRecord> {
    let (rec, time, truth_params) = make_record(effect, seed, o.duration_s, o.rate_hz)?;
    let d = diagnose(&rec, time, Some(base), dopt)?;
    let truth_c = effect.and_then(|e| d.candidates.iter().find(|c| c.effect == e));
    Ok(BenchRecord {
        seed,
        truth: effect.map_or("none", Effect::name).to_string(),
        truth_params,
        diagnosed: d.effect.clone(),
        best_candidate: d.best_candidate,
        gap_before: d.gap_before,
        null_gap_95: d.null_gap_95,
        null_gap_median: d.null_gap_median,
        gap_after_true_effect: truth_c.and_then(|c| c.gap_after),
        shrink: d.shrink,
        shrink_true_effect: truth_c.and_then(|c| c.shrink),
        candidates: d.candidates.clone(),
    })
}

fn summarise(records: Vec<BenchRecord>, o: &BenchOptions, seconds: f64) -> BenchReport {
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut classes = BTreeMap::new();
    for r in &records {
        *confusion
            .entry(r.truth.clone())
            .or_default()
            .entry(r.diagnosed.clone())
            .or_default() += 1;
    }
    for c in &o.classes {
        let name = c.map_or("none", Effect::name).to_string();
        let rs: Vec<&BenchRecord> = records.iter().filter(|r| r.truth == name).collect();
        let shrinks: Vec<f64> = rs
            .iter()
            .map(|r| r.shrink_true_effect.unwrap_or(r.shrink))
            .collect();
        classes.insert(
            name.clone(),
            ClassSummary {
                records: rs.len(),
                correct: rs.iter().filter(|r| r.diagnosed == name).count(),
                median_shrink: super::features::median(&shrinks),
            },
        );
    }
    let with: Vec<&BenchRecord> = records.iter().filter(|r| r.truth != "none").collect();
    let without: Vec<&BenchRecord> = records.iter().filter(|r| r.truth == "none").collect();
    // One definition, the matrix's: its diagonal over its total.
    let right: usize = confusion
        .iter()
        .filter_map(|(truth, row)| row.get(truth))
        .sum();
    let total: usize = confusion.values().flat_map(|row| row.values()).sum();
    let right_rate = right as f64 / total.max(1) as f64;
    let none_false_rate = without.iter().filter(|r| r.diagnosed != "none").count() as f64
        / without.len().max(1) as f64;
    let median_shrink = super::features::median(
        &with
            .iter()
            .map(|r| r.shrink_true_effect.unwrap_or(0.0))
            .collect::<Vec<_>>(),
    );
    BenchReport {
        setup: format!(
            "{} records per class, {} s at {} Hz, {} simulations per model, first seed {}",
            o.per_effect, o.duration_s, o.rate_hz, o.seeds, o.first_seed
        ),
        goals_met: right_rate >= 0.9 && none_false_rate <= 0.1 && median_shrink >= 0.7,
        records,
        confusion,
        classes,
        right,
        total,
        right_rate,
        none_false_rate,
        median_shrink,
        seconds,
    }
}

/// The confusion matrix and per-class figures as a Markdown table.
pub fn table(r: &BenchReport) -> String {
    let mut cols: Vec<String> = vec!["none".into()];
    cols.extend(ALL.iter().map(|e| e.name().to_string()));
    let short = |c: &str| -> String {
        c.split('_')
            .map(|w| w.chars().take(4).collect::<String>())
            .collect::<Vec<_>>()
            .join("_")
    };
    let mut s = String::new();
    s.push_str("| truth \\ named | ");
    s.push_str(
        &cols
            .iter()
            .map(|c| short(c))
            .collect::<Vec<_>>()
            .join(" | "),
    );
    s.push_str(" | right | median shrink |\n|---|");
    s.push_str(&"---|".repeat(cols.len() + 2));
    s.push('\n');
    for (name, c) in &r.classes {
        let row = r.confusion.get(name);
        s.push_str(&format!("| {name} | "));
        s.push_str(
            &cols
                .iter()
                .map(|col| {
                    row.and_then(|m| m.get(col))
                        .map_or(".".to_string(), |n| n.to_string())
                })
                .collect::<Vec<_>>()
                .join(" | "),
        );
        s.push_str(&format!(
            " | {}/{} | {:.2} |\n",
            c.correct, c.records, c.median_shrink
        ));
    }
    let none_flagged = r
        .records
        .iter()
        .filter(|x| x.truth == "none" && x.diagnosed != "none")
        .count();
    let nones = r.records.iter().filter(|x| x.truth == "none").count();
    s.push_str(&format!(
        "\nright effect named: {} of {} records = {:.1} % ({RIGHT_DEFINITION}; goal >= 90 %)\n",
        r.right,
        r.total,
        100.0 * r.right_rate
    ));
    s.push_str(&format!(
        "none wrongly flagged: {none_flagged} of {nones} = {:.1} % (goal <= 10 %); median shrink of the true effect: {:.2} (goal >= 0.7); goals met: {}; {:.0} s\n",
        100.0 * r.none_false_rate,
        r.median_shrink,
        r.goals_met,
        r.seconds
    ));
    s
}
