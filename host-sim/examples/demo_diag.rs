//! Why the demo's identifier trails the gated Kalman filter on its vehicle record:
//! `cargo run --release -p host-sim --example demo_diag`
//!
//! The demo's family, training records (units 1..12, seeds 101..), validation vehicles
//! (units 800.., seeds 201..) and vehicle record (unit 900, seed 7), 1800 s at 100 Hz.
//! Heading-error RMS (deg) on the demo's vehicle record and the mean over 8 validation
//! vehicles, for: the gated Kalman filter (truth flags and the identifier's own flags);
//! the identifier with its level noise over a grid, window and sample update, trained and
//! untrained model, own detector and truth as external flag.

use anyhow::Result;
use fog_core::motion::{
    LevelUpdate, MotionConfig, MotionEstimator, MotionModel, MotionTrainer, MOTION_DRLS,
};
use fog_core::still::SensorConfig;
use host_sim::demo::{family_model, RATE_HZ, VEHICLE_SEED, VEHICLE_UNIT};
use host_sim::nav::{log_grid, run, DriftEstimator, GatedKalman, NavRecord};
use host_sim::sim::Simulator;

const DURATION_S: f64 = 1800.0;

fn record(unit: u64, seed: u64, vehicle: bool) -> Result<NavRecord> {
    let mut s = Simulator::new(&family_model(unit, vehicle)?, seed, RATE_HZ)?;
    let v: Vec<_> = (0..(DURATION_S * RATE_HZ) as usize)
        .map(|_| s.next_sample())
        .collect();
    Ok(NavRecord::from_samples(&v))
}

struct Motion {
    est: MotionEstimator,
    truth: bool,
    calls: Vec<bool>,
}

impl DriftEstimator for Motion {
    fn name(&self) -> String {
        "motion".into()
    }
    fn push(&mut self, _: f64, rate_dps: f64, temp_c: Option<f64>, still: bool) -> f64 {
        let temp = temp_c.map_or(f32::NAN, |t| t as f32);
        match self
            .est
            .push(rate_dps as f32, temp, self.truth.then_some(still))
        {
            Ok(o) => {
                self.calls.push(o.still);
                f64::from(o.drift_dps)
            }
            Err(_) => {
                self.calls.push(false);
                0.0
            }
        }
    }
}

fn motion(model: &MotionModel, q_dph2_per_h: f64, update: LevelUpdate, truth: bool) -> Motion {
    let mut cfg = MotionConfig::for_sensor(SensorConfig::ECORE_2000);
    cfg.level_q_dps2_per_s = (q_dph2_per_h / 3600f64.powi(3)) as f32;
    let est = MotionEstimator::new(*model, cfg)
        .expect("valid configuration")
        .with_level_update(update);
    Motion {
        est,
        truth,
        calls: Vec::new(),
    }
}

fn main() -> Result<()> {
    let sensor = SensorConfig::ECORE_2000;
    let mut tr = MotionTrainer::new(
        MotionModel::standard(DURATION_S as f32).map_err(|e| anyhow::anyhow!("{e}"))?,
        MOTION_DRLS,
        1.0,
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let train: Vec<NavRecord> = (0..12)
        .map(|i| record(i + 1, 101 + i, false))
        .collect::<Result<_>>()?;
    for _ in 0..3 {
        for r in &train {
            let rate: Vec<f32> = r.rate_dps.iter().map(|&x| x as f32).collect();
            let temp: Vec<f32> = r.temp_c.iter().flatten().map(|&x| x as f32).collect();
            tr.train_record(&rate, Some(&temp), sensor.sample_rate_hz)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
    }
    let trained = *tr.model();
    let untrained = MotionModel::standard(DURATION_S as f32).map_err(|e| anyhow::anyhow!("{e}"))?;
    let val: Vec<NavRecord> = (0..8)
        .map(|i| record(800 + i, 201 + i, true))
        .collect::<Result<_>>()?;
    let veh = record(VEHICLE_UNIT, VEHICLE_SEED, true)?;
    let still = veh.still_truth();
    println!(
        "demo vehicle record: {:.1} % still (truth)",
        100.0 * still.iter().filter(|&&s| s).count() as f64 / still.len() as f64
    );
    let r = f64::from(sensor.sample_var_dps2());
    println!("{:<44} {:>10} {:>10}", "estimator", "vehicle", "valid x8");
    for q in log_grid(1e-16, 1e-8, 2) {
        let v: f64 = val
            .iter()
            .map(|x| {
                run(x, &mut GatedKalman::new(q, r), &x.still_truth())
                    .scores
                    .heading_rms_deg
            })
            .sum::<f64>()
            / val.len() as f64;
        let h = run(&veh, &mut GatedKalman::new(q, r), &still)
            .scores
            .heading_rms_deg;
        println!(
            "{:<44} {h:>10.4} {v:>10.4}",
            format!("gated Kalman truth, q {q:.1e}/sample")
        );
    }
    use LevelUpdate::{Sample, Window};
    for (name, model, update, truth) in [
        ("window", &trained, Window, false),
        ("sample", &trained, Sample, false),
        ("window untrained", &untrained, Window, false),
        ("sample untrained", &untrained, Sample, false),
        ("window truth flags", &trained, Window, true),
        ("sample truth flags", &trained, Sample, true),
    ] {
        for q in log_grid(1.0, 16384.0, 1) {
            let mut m = motion(model, q, update, truth);
            let o = run(&veh, &mut m, &still);
            // Gated Kalman on the identifier's own calls (the replay's baseline flags).
            let calls = m.calls.clone();
            let v: f64 = val
                .iter()
                .map(|x| {
                    run(x, &mut motion(model, q, update, truth), &x.still_truth())
                        .scores
                        .heading_rms_deg
                })
                .sum::<f64>()
                / val.len() as f64;
            let (mut fs, mut ms, mut nm, mut ns) = (0, 0, 0, 0);
            for (mv, c) in veh.moving.iter().zip(&calls) {
                if *mv {
                    nm += 1;
                    fs += usize::from(*c);
                } else {
                    ns += 1;
                    ms += usize::from(!*c);
                }
            }
            println!(
                "{:<44} {:>10.4} {v:>10.4}  false-still {:.2} % missed {:.2} %",
                format!("motion {name}, q {q:.0} (deg/h)^2/h"),
                o.scores.heading_rms_deg,
                100.0 * fs as f64 / nm.max(1) as f64,
                100.0 * ms as f64 / ns.max(1) as f64
            );
        }
    }
    Ok(())
}
