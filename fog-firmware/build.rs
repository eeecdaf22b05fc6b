//! Link setup: the board's memory map as `memory.x`, cortex-m-rt's `link.x`, defmt's
//! `defmt.x`. The linker arguments are given here rather than in `.cargo/config.toml` so that a
//! `RUSTFLAGS` in the environment (which replaces the config's `rustflags`) cannot drop them.
use std::path::PathBuf;
use std::{env, fs};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    // The QEMU board uses the repository's memory.x; the STM32F407 its own (1 MiB flash,
    // 128 KiB SRAM).
    let memory = if env::var_os("CARGO_FEATURE_BOARD_STM32F407").is_some() {
        manifest.join("memory-stm32f407.x")
    } else {
        manifest.join("../memory.x")
    };
    fs::copy(&memory, out.join("memory.x")).expect("memory map copied to OUT_DIR");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rerun-if-changed=build.rs");
    for arg in ["--nmagic", "-Tlink.x", "-Tdefmt.x"] {
        println!("cargo:rustc-link-arg-bins={arg}");
    }
}
