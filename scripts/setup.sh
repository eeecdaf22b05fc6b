#!/usr/bin/env bash
# Installs what the project needs on a fresh machine of this kind (idempotent):
# - the Rust toolchain, components and targets pinned in rust-toolchain.toml (rustup);
# - qemu-system-arm for the firmware's hardware-in-the-loop tests, when the firmware exists.
set -euo pipefail
cd "$(dirname "$0")/.."

channel=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
rustup toolchain install "$channel" --profile minimal --component clippy,rustfmt --target thumbv7em-none-eabihf >/dev/null 2>&1 \
  || rustup toolchain install "$channel" --profile minimal --component clippy,rustfmt --target thumbv7em-none-eabihf
rustup target add --toolchain "$channel" thumbv7em-none-eabihf >/dev/null

if [ -d fog-firmware ] && ! command -v qemu-system-arm >/dev/null 2>&1; then
  echo "setup: installing qemu-system-arm" >&2
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq qemu-system-arm >/dev/null
fi
