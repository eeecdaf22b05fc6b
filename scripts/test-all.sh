#!/usr/bin/env bash
# Runs every check and test of the project; installs what it needs first.
# This is the README's test command and what CI (.ci/run) calls.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

step() { printf '\n==> %s\n' "$*" >&2; }
step "rustfmt"
cargo fmt --all -- --check
step "clippy (host workspace, -D warnings)"
cargo clippy --workspace --all-targets -- -D warnings
step "fog-core builds no_std for the Cortex-M4F (with and without defmt)"
cargo build -q -p fog-core --target thumbv7em-none-eabihf
cargo build -q -p fog-core --target thumbv7em-none-eabihf --features defmt
cargo clippy -q -p fog-core --target thumbv7em-none-eabihf --features defmt -- -D warnings
step "tests (host workspace)"
cargo test --workspace
