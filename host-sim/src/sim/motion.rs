//! Platform motion: the true rate the gyro is turned at, and whether the platform moves.
//!
//! A `[motion]` section picks a `profile`:
//! - `constant` (default; `sine` is the same profile): `rate_dps + sine_amplitude_dps
//!   sin(2 pi sine_freq_hz t)`, today's behaviour, bit for bit.
//! - `vehicle` (`[motion.vehicle]`): seeded. A still alignment period of `align_s`, then
//!   drives and stops in turn. A drive lasts `U(drive_min_s, drive_max_s)`; its speed ramps
//!   up and down (raised cosine over `ramp_s`); its yaw rate is speed x road curvature, the
//!   curvature cosine-interpolated between random knots `curvature_length_m` apart
//!   (`N(0, curvature_sigma_per_m)`), the road yaw rate clipped at `road_rate_max_dps`; turns
//!   (mean interval `turn_interval_s`, exponential) add a raised-cosine rate hump of peak
//!   `U(turn_rate_min_dps, turn_rate_max_dps)` and angle `U(turn_angle_min_deg,
//!   turn_angle_max_deg)` with a random sign (it lasts `2 angle / peak` s). A stop lasts
//!   `U(stop_min_s, stop_max_s)`, rate exactly 0.
//! - `turntable` (`[[motion.turntable.step]]`): a schedule of steps, each a constant rate
//!   for `duration_s` (rate 0 = a hold) or an angle step `angle_deg` at `|rate_dps|`.
//! - `file`: the true rate from a CSV `t_s,true_rate_dps` (header required, `t_s` strictly
//!   increasing), linearly interpolated, the end values held outside its time span.
//!
//! In every profile `rate_dps` and the sine add to the profile's rate. `moving` is the
//! ground truth for stillness detectors: for `vehicle`, the platform is moving during a
//! whole drive (even where the yaw rate crosses 0); for the other profiles, when the
//! platform rate (Earth rate excluded) is not exactly 0.

use anyhow::{bail, Context, Result};
use rand::Rng;
use rand_distr::{Distribution, Exp, StandardNormal};
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};

use super::model::Motion;

/// `[motion] profile`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    /// Constant rate plus sine (today's motion; `sine` is accepted as a synonym).
    #[default]
    #[serde(alias = "sine")]
    Constant,
    /// Seeded vehicle: alignment, drives with road curvature and turns, stops.
    Vehicle,
    /// A schedule of rates and angle steps.
    Turntable,
    /// True rate from a CSV file.
    File,
}

/// `[motion.vehicle]`: statistics of the vehicle profile. Every default is an ASSUMED,
/// plausible road vehicle (not measured).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Vehicle {
    /// Still alignment period at the start, s (default 300).
    pub align_s: f64,
    /// Stop length, uniform between these, s (default 5 .. 60).
    pub stop_min_s: f64,
    /// See `stop_min_s`.
    pub stop_max_s: f64,
    /// Drive length, uniform between these, s (default 30 .. 300).
    pub drive_min_s: f64,
    /// See `drive_min_s`.
    pub drive_max_s: f64,
    /// Speed ramp at the start and the end of a drive, s (default 5).
    pub ramp_s: f64,
    /// Cruise speed, m/s (default 15).
    pub speed_mps: f64,
    /// Road curvature (1 / radius) standard deviation, 1/m (default 5e-4: 2 km radius;
    /// at 15 m/s, 0.43 deg/s).
    pub curvature_sigma_per_m: f64,
    /// Distance between curvature knots, m (default 300).
    pub curvature_length_m: f64,
    /// Road yaw rate clipped at +/- this, deg/s (default 3).
    pub road_rate_max_dps: f64,
    /// Mean time between turns while driving, s (default 60; exponential).
    pub turn_interval_s: f64,
    /// Turn peak rate, uniform between these, deg/s (default 5 .. 30).
    pub turn_rate_min_dps: f64,
    /// See `turn_rate_min_dps`.
    pub turn_rate_max_dps: f64,
    /// Turn angle, uniform between these, deg (default 20 .. 120), random sign.
    pub turn_angle_min_deg: f64,
    /// See `turn_angle_min_deg`.
    pub turn_angle_max_deg: f64,
}

impl Default for Vehicle {
    fn default() -> Self {
        Self {
            align_s: 300.0,
            stop_min_s: 5.0,
            stop_max_s: 60.0,
            drive_min_s: 30.0,
            drive_max_s: 300.0,
            ramp_s: 5.0,
            speed_mps: 15.0,
            curvature_sigma_per_m: 5e-4,
            curvature_length_m: 300.0,
            road_rate_max_dps: 3.0,
            turn_interval_s: 60.0,
            turn_rate_min_dps: 5.0,
            turn_rate_max_dps: 30.0,
            turn_angle_min_deg: 20.0,
            turn_angle_max_deg: 120.0,
        }
    }
}

impl Vehicle {
    /// Long-run fraction of time the vehicle is still (alignment excluded):
    /// `E[stop] / (E[stop] + E[drive])`.
    pub fn still_fraction(&self) -> f64 {
        let stop = 0.5 * (self.stop_min_s + self.stop_max_s);
        let drive = 0.5 * (self.drive_min_s + self.drive_max_s);
        stop / (stop + drive)
    }

    /// Largest |yaw rate| the profile can produce, deg/s.
    pub fn max_rate_dps(&self) -> f64 {
        self.road_rate_max_dps + self.turn_rate_max_dps
    }
}

/// `[motion.turntable]`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Turntable {
    /// The steps, in order (`[[motion.turntable.step]]`).
    pub step: Vec<TurntableStep>,
    /// Start again after the last step (default false: still after it).
    pub repeat: bool,
}

/// `[[motion.turntable.step]]`: `duration_s` at `rate_dps` (0 = hold), or an angle step of
/// `angle_deg` at `|rate_dps|` (sign from the angle; lasts `|angle_deg / rate_dps|`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TurntableStep {
    /// Rate, deg/s (default 0).
    #[serde(default)]
    pub rate_dps: f64,
    /// Length of a constant-rate step or hold, s.
    pub duration_s: Option<f64>,
    /// Angle of an angle step, deg.
    pub angle_deg: Option<f64>,
}

impl TurntableStep {
    /// (signed rate deg/s, duration s) of a valid step.
    fn rate_and_duration(&self) -> (f64, f64) {
        match (self.angle_deg, self.duration_s) {
            (Some(a), _) if self.rate_dps != 0.0 => {
                (self.rate_dps.abs() * a.signum(), (a / self.rate_dps).abs())
            }
            (_, Some(d)) => (self.rate_dps, d),
            _ => (0.0, 0.0),
        }
    }
}

impl Turntable {
    /// Checks the steps; on error (step index from 0, key, message).
    pub(crate) fn check(&self) -> Result<(), (usize, &'static str, String)> {
        for (i, s) in self.step.iter().enumerate() {
            let bad = |k, m: &str| Err((i, k, m.to_string()));
            if !s.rate_dps.is_finite() {
                return bad("rate_dps", "must be finite");
            }
            match (s.angle_deg, s.duration_s) {
                (Some(_), Some(_)) => {
                    return bad("angle_deg", "give angle_deg or duration_s, not both")
                }
                (None, None) => return bad("duration_s", "give duration_s or angle_deg"),
                (Some(a), None) if !a.is_finite() => return bad("angle_deg", "must be finite"),
                (Some(_), None) if s.rate_dps == 0.0 => {
                    return bad("rate_dps", "an angle step needs a rate != 0")
                }
                (None, Some(d)) if !(d.is_finite() && d > 0.0) => {
                    return bad("duration_s", "must be finite and > 0")
                }
                _ => {}
            }
        }
        if self.repeat && self.step.iter().all(|s| s.rate_and_duration().1 <= 0.0) {
            return Err((
                0,
                "duration_s",
                "a repeated schedule needs a length > 0".into(),
            ));
        }
        Ok(())
    }
}

/// A validated turntable schedule.
#[derive(Debug, Clone)]
struct Schedule {
    /// (start s, rate deg/s) of each step, then the end time.
    starts_s: Vec<f64>,
    rates_dps: Vec<f64>,
    period_s: f64,
    repeat: bool,
}

impl Schedule {
    fn new(t: &Turntable) -> Self {
        let mut starts_s = Vec::with_capacity(t.step.len());
        let mut rates_dps = Vec::with_capacity(t.step.len());
        let mut t0 = 0.0;
        for s in &t.step {
            let (r, d) = s.rate_and_duration();
            starts_s.push(t0);
            rates_dps.push(r);
            t0 += d;
        }
        Self {
            starts_s,
            rates_dps,
            period_s: t0,
            repeat: t.repeat,
        }
    }

    fn rate_dps(&self, t_s: f64) -> f64 {
        let t = if self.repeat && self.period_s > 0.0 {
            t_s.rem_euclid(self.period_s)
        } else {
            t_s
        };
        if t < 0.0 || t >= self.period_s {
            return 0.0;
        }
        let i = self.starts_s.partition_point(|&s| s <= t);
        i.checked_sub(1).map_or(0.0, |i| self.rates_dps[i])
    }
}

/// True rate read from a `t_s,true_rate_dps` CSV file.
#[derive(Debug, Clone, PartialEq)]
pub struct RateTable {
    /// Times, s, strictly increasing.
    pub t_s: Vec<f64>,
    /// True rate at each time, deg/s.
    pub rate_dps: Vec<f64>,
}

impl RateTable {
    /// Reads a CSV (or `.csv.gz`) with a header holding `t_s` and `true_rate_dps` (other
    /// columns ignored), with [`crate::record::Record::read`]: errors name the file and
    /// the line (header = line 1).
    pub fn read(path: &Path) -> Result<Self> {
        let opts = crate::record::ReadOptions {
            optional_columns: false,
            ..crate::record::ReadOptions::rate("true_rate_dps", 1.0)
        };
        let r = crate::record::Record::read(path, &opts)?;
        if r.len() < 2 {
            bail!("{}: needs at least 2 rows, found {}", r.name, r.len());
        }
        Ok(Self {
            t_s: r.t_s,
            rate_dps: r.rate_dps,
        })
    }

    /// Linearly interpolated rate at `t_s`, deg/s; the end values outside the span.
    pub fn rate_at(&self, t_s: f64) -> f64 {
        let n = self.t_s.len();
        let i = self.t_s.partition_point(|&t| t <= t_s);
        match i {
            0 => self.rate_dps[0],
            i if i >= n => self.rate_dps[n - 1],
            i => {
                let (t0, t1) = (self.t_s[i - 1], self.t_s[i]);
                let (r0, r1) = (self.rate_dps[i - 1], self.rate_dps[i]);
                r0 + (r1 - r0) * (t_s - t0) / (t1 - t0)
            }
        }
    }

    /// Last time of the table, s.
    pub fn end_s(&self) -> f64 {
        self.t_s.last().copied().unwrap_or(0.0)
    }
}

/// One turn inside a drive.
#[derive(Debug, Clone, Copy)]
struct Turn {
    start_s: f64,
    duration_s: f64,
    peak_dps: f64,
}

/// The current segment of a vehicle run.
#[derive(Debug, Clone)]
struct Segment {
    start_s: f64,
    end_s: f64,
    drive: bool,
    /// Curvature knots, 1/m, `knot_s` apart from `start_s`.
    knots_per_m: Vec<f64>,
    knot_s: f64,
    turns: Vec<Turn>,
}

/// Streaming generator of the vehicle profile (its own random stream).
#[derive(Debug, Clone)]
struct VehicleGen {
    p: Vehicle,
    rng: Pcg64Mcg,
    seg: Segment,
    next_drive: bool,
}

impl VehicleGen {
    fn new(p: Vehicle, rng: Pcg64Mcg) -> Self {
        Self {
            p,
            rng,
            seg: Segment {
                start_s: 0.0,
                end_s: p.align_s,
                drive: false,
                knots_per_m: Vec::new(),
                knot_s: 1.0,
                turns: Vec::new(),
            },
            next_drive: true,
        }
    }

    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.rng.random::<f64>()
    }

    fn next_segment(&mut self) {
        let p = self.p;
        let start_s = self.seg.end_s;
        let drive = self.next_drive;
        self.next_drive = !drive;
        if !drive {
            let d = self.uniform(p.stop_min_s, p.stop_max_s);
            self.seg = Segment {
                start_s,
                end_s: start_s + d,
                drive,
                knots_per_m: Vec::new(),
                knot_s: 1.0,
                turns: Vec::new(),
            };
            return;
        }
        let d = self.uniform(p.drive_min_s, p.drive_max_s);
        let knot_s = p.curvature_length_m / p.speed_mps;
        let n = (d / knot_s).ceil() as usize + 2;
        let knots_per_m = (0..n)
            .map(|_| {
                let z: f64 = self.rng.sample(StandardNormal);
                z * p.curvature_sigma_per_m
            })
            .collect();
        let mut turns = Vec::new();
        let end_s = start_s + d;
        if let Ok(exp) = Exp::new(1.0 / p.turn_interval_s) {
            let mut t = start_s + p.ramp_s;
            loop {
                t += exp.sample(&mut self.rng);
                let peak = self.uniform(p.turn_rate_min_dps, p.turn_rate_max_dps);
                let angle = self.uniform(p.turn_angle_min_deg, p.turn_angle_max_deg);
                let sign = if self.rng.random::<bool>() { 1.0 } else { -1.0 };
                let dur = 2.0 * angle / peak;
                if t + dur > end_s - p.ramp_s {
                    break;
                }
                turns.push(Turn {
                    start_s: t,
                    duration_s: dur,
                    peak_dps: sign * peak,
                });
                t += dur;
            }
        }
        self.seg = Segment {
            start_s,
            end_s,
            drive,
            knots_per_m,
            knot_s,
            turns,
        };
    }

    /// (rate deg/s, moving) at `t_s`; `t_s` must not go backwards by more than a segment.
    fn at(&mut self, t_s: f64) -> (f64, bool) {
        while t_s >= self.seg.end_s {
            self.next_segment();
        }
        let s = &self.seg;
        if !s.drive || t_s < s.start_s {
            return (0.0, false);
        }
        let p = &self.p;
        let u = t_s - s.start_s;
        let ramp = |x: f64| {
            if p.ramp_s <= 0.0 || x >= p.ramp_s {
                1.0
            } else {
                0.5 * (1.0 - (PI * x.max(0.0) / p.ramp_s).cos())
            }
        };
        let envelope = ramp(u) * ramp(s.end_s - t_s);
        let x = u / s.knot_s;
        let i = (x.floor() as usize).min(s.knots_per_m.len().saturating_sub(2));
        let f = (x - i as f64).clamp(0.0, 1.0);
        let w = 0.5 * (1.0 - (PI * f).cos());
        let c0 = s.knots_per_m.get(i).copied().unwrap_or(0.0);
        let c1 = s.knots_per_m.get(i + 1).copied().unwrap_or(0.0);
        let curvature = c0 + (c1 - c0) * w;
        let road = (envelope * p.speed_mps * curvature)
            .to_degrees()
            .clamp(-p.road_rate_max_dps, p.road_rate_max_dps);
        let turn: f64 = s
            .turns
            .iter()
            .filter(|tn| t_s >= tn.start_s && t_s < tn.start_s + tn.duration_s)
            .map(|tn| tn.peak_dps * 0.5 * (1.0 - (TAU * (t_s - tn.start_s) / tn.duration_s).cos()))
            .sum();
        (road + turn, true)
    }
}

/// Platform motion of a [`Motion`] section, sample by sample.
#[derive(Debug, Clone)]
pub struct Platform {
    rate_dps: f64,
    sine_amplitude_dps: f64,
    sine_freq_hz: f64,
    kind: Kind,
}

#[derive(Debug, Clone)]
enum Kind {
    Constant,
    Vehicle(Box<VehicleGen>),
    Turntable(Schedule),
    File(RateTable),
}

/// The platform at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformState {
    /// Platform rate about the sensitive axis, deg/s (Earth rate not included).
    pub rate_dps: f64,
    /// Ground truth: the platform is moving (see the module docs).
    pub moving: bool,
}

impl Platform {
    /// Platform of `motion` (validated); `rng` drives the vehicle profile. Reads the file of
    /// the `file` profile.
    pub fn new(motion: &Motion, rng: Pcg64Mcg) -> Result<Self> {
        let kind = match motion.profile {
            Profile::Constant => Kind::Constant,
            Profile::Vehicle => Kind::Vehicle(Box::new(VehicleGen::new(motion.vehicle, rng))),
            Profile::Turntable => Kind::Turntable(Schedule::new(&motion.turntable)),
            Profile::File => {
                let path: &PathBuf = motion
                    .file
                    .as_ref()
                    .context("[motion] profile = \"file\" needs `file = \"PATH.csv\"`")?;
                Kind::File(RateTable::read(path)?)
            }
        };
        Ok(Self {
            rate_dps: motion.rate_dps,
            sine_amplitude_dps: motion.sine_amplitude_dps,
            sine_freq_hz: motion.sine_freq_hz,
            kind,
        })
    }

    /// The platform at `t_s` (non-decreasing from call to call for the vehicle profile).
    pub fn at(&mut self, t_s: f64) -> PlatformState {
        let base = self.rate_dps + self.sine_amplitude_dps * (TAU * self.sine_freq_hz * t_s).sin();
        let (rate_dps, moving) = match &mut self.kind {
            Kind::Constant => (base, base != 0.0),
            Kind::Vehicle(v) => {
                let (r, m) = v.at(t_s);
                (base + r, m || base != 0.0)
            }
            Kind::Turntable(s) => {
                let r = base + s.rate_dps(t_s);
                (r, r != 0.0)
            }
            Kind::File(f) => {
                let r = base + f.rate_at(t_s);
                (r, r != 0.0)
            }
        };
        PlatformState { rate_dps, moving }
    }

    /// End of the file profile's time span, s (None for other profiles).
    pub fn file_end_s(&self) -> Option<f64> {
        match &self.kind {
            Kind::File(f) => Some(f.end_s()),
            _ => None,
        }
    }
}
