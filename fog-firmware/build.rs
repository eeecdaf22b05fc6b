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
    rt_feed(&out);
    identifier(&out, &manifest);
    for arg in ["--nmagic", "-Tlink.x", "-Tdefmt.x"] {
        println!("cargo:rustc-link-arg-bins={arg}");
    }
}

/// The identifier image the firmware embeds: the file named by `FOG_IDENTIFIER`, else the
/// committed `identifier/default.fogi` (made by `scripts/train-default-identifier.sh`),
/// copied to `OUT_DIR/identifier.fogi` as it is. It is not checked here: the firmware parses
/// and checks it at boot (a corrupt or wrong-rate image stops it with an error there).
fn identifier(out: &std::path::Path, manifest: &std::path::Path) {
    println!("cargo:rerun-if-env-changed=FOG_IDENTIFIER");
    let file = env::var_os("FOG_IDENTIFIER")
        .map(PathBuf::from)
        .unwrap_or_else(|| manifest.join("identifier/default.fogi"));
    println!("cargo:rerun-if-changed={}", file.display());
    let bytes = fs::read(&file).unwrap_or_else(|e| {
        panic!(
            "identifier image {} unreadable ({e}); set FOG_IDENTIFIER or run scripts/train-default-identifier.sh",
            file.display()
        )
    });
    fs::write(out.join("identifier.fogi"), bytes).expect("OUT_DIR writable");
}

/// Feature `rt-feed` (test build): the capture named by `FOG_RT_CAPTURE` goes into the image,
/// and the byte period (10 bits: start, 8 data, stop) at `FOG_RT_BAUD` (default 115200) on a
/// modelled 168 MHz core (one instruction per cycle) becomes timer ticks at QEMU's 1.6 ticks
/// per instruction.
fn rt_feed(out: &std::path::Path) {
    println!("cargo:rerun-if-env-changed=FOG_RT_CAPTURE");
    println!("cargo:rerun-if-env-changed=FOG_RT_BAUD");
    if env::var_os("CARGO_FEATURE_RT_FEED").is_none() {
        return;
    }
    let capture = env::var_os("FOG_RT_CAPTURE")
        .expect("feature rt-feed: set FOG_RT_CAPTURE to the capture file to deliver");
    println!(
        "cargo:rerun-if-changed={}",
        PathBuf::from(&capture).display()
    );
    let bytes = fs::read(&capture).expect("FOG_RT_CAPTURE readable");
    fs::write(out.join("rt_capture.bin"), bytes).expect("OUT_DIR writable");
    let baud: u64 = env::var("FOG_RT_BAUD")
        .map(|b| b.parse().expect("FOG_RT_BAUD: a positive integer"))
        .unwrap_or(115_200);
    assert!(
        (1_000..=10_000_000).contains(&baud),
        "FOG_RT_BAUD out of range"
    );
    const MODEL_CLOCK_HZ: u64 = 168_000_000;
    // Ticks = instructions * 1.6 = (168e6 * 10 / baud) * 16 / 10 = 168e6 * 16 / baud, rounded.
    let ticks = (MODEL_CLOCK_HZ * 16 + baud / 2) / baud;
    fs::write(
        out.join("rt_feed_config.rs"),
        format!(
            "/// Line rate, bit/s.\npub const BAUD: u32 = {baud};\n\
             /// Timer ticks per byte (1.6 per instruction under -icount shift=6).\n\
             pub const BYTE_PERIOD_TICKS: u32 = {ticks};\n"
        ),
    )
    .expect("OUT_DIR writable");
}
