//! `host-sim` as a library: the modules behind the subcommands, for tests, benches and
//! other subcommands (the simulator in [`sim`], Allan analysis in [`allan`]).
#![forbid(unsafe_code)]

pub mod allan;
pub mod allan_cmd;
pub mod demo;
pub mod demo_cmd;
pub mod denoise_cmd;
pub mod firmware_fit;
pub mod gap;
pub mod gap_cmd;
pub mod gyro;
pub mod gyro_cmd;
pub mod gyro_fit;
pub mod identify;
pub mod identify_cmd;
pub mod image_cmd;
pub mod motion;
pub mod nav;
pub mod record;
pub mod record_args;
pub mod replay;
pub mod replay_cmd;
pub mod report;
pub mod reproduce_cmd;
pub mod sensor;
pub mod sim;
pub mod simulate_cmd;
