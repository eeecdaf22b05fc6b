//! Research apart from the product (issue "One product a newcomer can read"): evaluations
//! and comparisons that drive the built `host-sim` binary or its library, each a binary in
//! `src/bin/`. Nothing in fog-core, host-sim or the firmware depends on this crate.
//!
//! - `unit_family`: the product (`host-sim identify` + `replay`) on gyro families
//!   (calibration runs, static test units, vehicles) beside causal baselines:
//!   `cargo run --release -p fog-lab --bin unit_family -- --family DIR [--json J]`.
//! - `drift_filter_eval`: the drift filter in memory on the same families, paired per
//!   vehicle with `unit_family`'s figures, with the limit (each vehicle's own model) and the
//!   demo's family: `docs/drift-filter.md` rests on it.
#![forbid(unsafe_code)]

pub mod static_rw;
