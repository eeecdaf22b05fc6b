#!/usr/bin/env bash
# Runs every check and test of the project; installs what it needs first.
# This is the README's test command and what CI (.ci/run) calls.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# setup.sh installed NumPy: the tests that run the independent generators must not skip.
export FOG_REQUIRE_NUMPY=1

# Each step says when it starts (seconds since the script started): where CI's time goes.
step() { printf '\n==> [%d s] %s\n' "$SECONDS" "$*" >&2; }
step "rustfmt"
cargo fmt --all -- --check
step "clippy (host workspace, -D warnings)"
cargo clippy --workspace --all-targets -- -D warnings
step "rustdoc (fog-core, host-sim, fog-lab; warnings are errors: broken or private links)"
RUSTDOCFLAGS="-D warnings" cargo doc -q -p fog-core -p host-sim -p fog-lab --no-deps
step "fog-core builds no_std for the Cortex-M4F (with and without defmt)"
cargo build -q -p fog-core --target thumbv7em-none-eabihf
cargo build -q -p fog-core --target thumbv7em-none-eabihf --features defmt
cargo clippy -q -p fog-core --target thumbv7em-none-eabihf --features defmt -- -D warnings
step "tests (host workspace, but the system tests)"
cargo test --workspace --exclude fog-system-tests
# The system tests (the firmware's hardware-in-the-loop tests under QEMU and its builds,
# tests/tests/): a debug and a release run at once, each in parallel.
# The system tests run the host-sim binary that step built (tests/src/lib.rs, host_sim):
# their own `cargo build -p host-sim` unifies other features and builds it again.
bin="${CARGO_TARGET_DIR:-target}/debug/host-sim"
[ -x "$bin" ] || { echo "test-all: the workspace tests did not build $bin" >&2; exit 1; }
step "system tests: debug and release runs at the same time"
FOG_HOST_SIM_BIN="$(cd "$(dirname "$bin")" && pwd)/host-sim" bash scripts/test-firmware-parallel.sh
# fog-firmware is its own workspace (defmt, cortex-m-rt): checked apart from the host crates. The STM32F407 board builds into its own target directory so
# that switching boards does not rebuild the QEMU board's dependencies.
step "fog-firmware: rustfmt, clippy -D warnings, build (QEMU mps2-an386, STM32F407 and its netduinoplus2 variant)"
(
  cd fog-firmware
  unset RUSTFLAGS
  cargo fmt -- --check
  cargo clippy -q --release -- -D warnings
  cargo clippy -q --release --features budget -- -D warnings
  # The real-time arrival test images (tests/tests/firmware_realtime.rs builds and runs them
  # with a capture; an empty one is enough to lint them).
  FOG_RT_CAPTURE=/dev/null cargo clippy -q --release --features rt-feed --target-dir target/rt -- -D warnings
  FOG_RT_CAPTURE=/dev/null cargo clippy -q --release --features rt-feed-poll --target-dir target/rt -- -D warnings
  cargo build -q --release
  cargo clippy -q --release --no-default-features --features board-stm32f407 --target-dir target/stm32 -- -D warnings
  cargo build -q --release --no-default-features --features board-stm32f407 --target-dir target/stm32
  # The STM32 build's QEMU variant (netduinoplus2; the HIL test in firmware_qemu.rs runs it).
  cargo clippy -q --release --no-default-features --features qemu-netduinoplus2 --target-dir target/netduino -- -D warnings
)

# Coverage-guided fuzzing (libFuzzer, plain cargo on the pinned stable toolchain): fuzz/ is its
# own workspace (instrumented build, libfuzzer-sys) like fog-firmware. Each target runs
# FUZZ_SECONDS (default 20) from its committed corpus; a crash fails the run. See
# docs/reliability.md.
step "fuzz: rustfmt, clippy -D warnings, every target ${FUZZ_SECONDS:-20} s"
(
  cd fuzz
  unset RUSTFLAGS
  cargo fmt -- --check
  cargo clippy -q --release --locked -- -D warnings
)
bash scripts/fuzz.sh
printf '\n==> [%d s] every check passed\n' "$SECONDS" >&2
