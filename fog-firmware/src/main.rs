//! fog firmware: E-Core 2000 frames in on a UART, one drift-identification record per good
//! frame out on the same UART, statistics on defmt. See `fog-firmware/README.md`.
#![no_std]
#![no_main]

#[cfg_attr(feature = "budget", allow(dead_code))]
mod app;
#[allow(unsafe_code)]
mod board;
#[cfg(feature = "budget")]
mod budget;
mod pipeline;
#[cfg_attr(feature = "budget", allow(dead_code))]
mod temperature;
#[cfg_attr(feature = "budget", allow(dead_code))]
mod temperature_hold;
