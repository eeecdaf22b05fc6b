#!/usr/bin/env bash
# Installs what the project needs on a fresh machine of this kind (idempotent):
# - the Rust toolchain, components and targets pinned in rust-toolchain.toml (rustup);
# - qemu-system-arm for the firmware's hardware-in-the-loop tests, when the firmware exists;
# - chromium (headless) for the test that loads the demo's index.html;
# - binutils-arm-none-eabi for the firmware's panic-path test;
# - a C++ compiler (g++) for libFuzzer, built by the fuzz crate (scripts/fuzz.sh); its C
#   compiler (cc) also builds the QEMU trace plugin of the cycle estimate
#   (scripts/qemu-trace/fogtrace.c, built by fw-cycles);
# - python3 with NumPy: the independent generators scripts/gen_nav_records.py and
#   scripts/gap_indep_gen.py, which host-sim/tests/second_generator.rs and gap_indep.rs run
#   (they fail without it when FOG_REQUIRE_NUMPY or CI is set; test-all.sh sets the first).
set -euo pipefail
cd "$(dirname "$0")/.."

# Debian packages, quietly, with sudo when not root.
apt_install() {
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@" >/dev/null
}

channel=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
# Only what is missing: `rustup toolchain install` on an installed toolchain reinstalls it,
# and while it does, every concurrent build fails.
if ! rustup run "$channel" rustc --version >/dev/null 2>&1; then
  echo "setup: installing Rust $channel" >&2
  rustup toolchain install "$channel" --profile minimal --component clippy,rustfmt --target thumbv7em-none-eabihf
fi
rustup target list --installed --toolchain "$channel" | grep -qx thumbv7em-none-eabihf \
  || rustup target add --toolchain "$channel" thumbv7em-none-eabihf
for c in clippy rustfmt; do
  rustup component list --installed --toolchain "$channel" | grep -q "^$c" \
    || rustup component add --toolchain "$channel" "$c"
done

if [ -d fog-firmware ] && ! command -v qemu-system-arm >/dev/null 2>&1; then
  echo "setup: installing qemu-system-arm" >&2
  apt_install qemu-system-arm
fi

# binutils for the Cortex-M (arm-none-eabi-objdump, -addr2line, -nm): the test that looks
# for panic paths in the release firmware (tests/tests/firmware_no_panic.rs).
if [ -d fog-firmware ] && ! command -v arm-none-eabi-objdump >/dev/null 2>&1 \
   && command -v apt-get >/dev/null 2>&1; then
  echo "setup: installing binutils-arm-none-eabi" >&2
  apt_install binutils-arm-none-eabi
fi

# A C++ compiler: libfuzzer-sys builds libFuzzer (scripts/fuzz.sh).
if { ! command -v c++ >/dev/null 2>&1 || ! command -v cc >/dev/null 2>&1; } \
   && command -v apt-get >/dev/null 2>&1; then
  echo "setup: installing g++" >&2
  apt_install g++
fi

# Headless Chromium for the test that opens the demo's index.html (it skips, saying why,
# when no browser is found).
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1 \
   && command -v apt-get >/dev/null 2>&1; then
  echo "setup: installing chromium" >&2
  apt_install chromium
fi

# NumPy for the independent generators (see the top): pip for the python3 on the PATH (a
# pyenv or venv python); where pip refuses (PEP 668: a distribution's own python) or is
# missing, Debian's python3-numpy, which serves /usr/bin/python3.
has_numpy() { command -v python3 >/dev/null 2>&1 && python3 -c "import numpy" >/dev/null 2>&1; }
if ! has_numpy; then
  if command -v python3 >/dev/null 2>&1 && python3 -m pip --version >/dev/null 2>&1; then
    echo "setup: installing numpy for $(command -v python3) with pip" >&2
    python3 -m pip install -q --disable-pip-version-check "numpy>=1.24,<3" 2>&1 \
      | grep -v "Running pip as the 'root' user" >&2 || true
  fi
  if ! has_numpy && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing python3 and python3-numpy with apt-get" >&2
    apt_install python3 python3-numpy
  fi
  has_numpy || { echo "setup: python3 with numpy could not be installed ($(command -v python3 || echo 'no python3'))" >&2; exit 1; }
fi
