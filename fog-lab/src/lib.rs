//! Research apart from the product (issue "One product a newcomer can read"): evaluations
//! and comparisons that drive the built `host-sim` binary or its library, each a binary in
//! `src/bin/`. Nothing in fog-core, host-sim or the firmware depends on this crate.
//!
//! - `unit_family`: the motion identifier on gyro families (calibration runs, static test
//!   units, vehicles) beside causal baselines; `docs/unit-fit.md` rests on it:
//!   `cargo run --release -p fog-lab --bin unit_family -- --family DIR [--json J]`.
#![forbid(unsafe_code)]
