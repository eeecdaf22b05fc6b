//! `host-sim replay`'s pipelines (the command file `replay_cmd.rs` parses arguments and
//! calls them):
//! - [`motion`]: the default, the drift filter (of an image, or of the sensor's
//!   specification alone) with the navigator's scores when the record has truth;
//! - [`stream`]: the level-trend and paper presets, streamed, with the paper's report;
//! - [`input`]: the record the motion pipeline reads, sample by sample (CSV with any rate
//!   column, or a decoded capture); [`tally`]: the summary's counts on line;
//! - [`pooled`]: a test set's result in one verdict (`host-sim demo`).

pub mod input;
pub mod motion;
pub mod pooled;
pub mod stream;
pub mod tally;
