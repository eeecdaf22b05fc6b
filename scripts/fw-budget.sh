#!/usr/bin/env bash
# Firmware budget: instructions per sample (QEMU mps2-an386 under -icount, SysTick calibrated
# with a counted loop), flash and RAM of the production ELF, stack high-water mark from the
# hardware-in-the-loop run. Prints the table and each goal's distance.
#   bash scripts/fw-budget.sh [CLOCK_MHZ SAMPLE_RATE_HZ]
# The firmware prints the budget at 168 MHz and 1 kHz; with CLOCK_MHZ and SAMPLE_RATE_HZ the
# script adds the same line for that clock and rate (from the measured mean and worst sample).
set -euo pipefail
clock_mhz=${1:-}
rate_hz=${2:-}
if [ -n "$clock_mhz" ] && ! [[ "$clock_mhz" =~ ^[0-9]+$ && "${rate_hz:-x}" =~ ^[0-9]+$ && "$rate_hz" -gt 0 ]]; then
  echo "usage: bash scripts/fw-budget.sh [CLOCK_MHZ SAMPLE_RATE_HZ] (positive integers)" >&2
  exit 2
fi
cd "$(dirname "$0")/.."
bash scripts/setup.sh
fw=fog-firmware
elf=$fw/target/thumbv7em-none-eabihf/release/fog-firmware
budget_elf=$fw/target/budget/thumbv7em-none-eabihf/release/fog-firmware

echo "==> building the production firmware and the budget variant (feature budget)" >&2
(cd $fw && env -u RUSTFLAGS cargo build -q --release)
(cd $fw && env -u RUSTFLAGS cargo build -q --release --features budget --target-dir target/budget)

echo "==> instructions per sample: qemu-system-arm -icount shift=6,align=off,sleep=off" >&2
table=$(timeout 120 qemu-system-arm -machine mps2-an386 -nographic -monitor none -serial stdio \
  -semihosting-config enable=on,target=native -icount shift=6,align=off,sleep=off \
  -kernel "$budget_elf" < /dev/null 2>/dev/null)
echo "$table"
if [ -n "$clock_mhz" ]; then
  # The whole-pipeline row: "| whole pipeline (decode+stage+record) | sample | MEAN | MAX |".
  read -r mean worst < <(awk -F'|' '/whole pipeline \(decode\+stage/ {gsub(/ /, "", $4); gsub(/ /, "", $5); print $4, $5}' <<<"$table")
  awk -v m="$mean" -v w="$worst" -v c="$clock_mhz" -v r="$rate_hz" 'BEGIN {
    avail = c * 1e6 / r;
    printf "budget at %d MHz, %d Hz: %d instructions per sample available; pipeline mean %.1f (%.2f %%), worst sample %.1f (%.2f sample periods); instructions, not cycles\n", c, r, avail, m, 100 * m / avail, w, w / avail }'
fi

echo
echo "==> memory of the production ELF ($elf), from size -A"
# Sections: flash = vector table + text + rodata + data (its load image); static RAM = data +
# bss + uninit.
read -r vt text rodata data bss uninit < <(size -A "$elf" | awk '
  $1==".vector_table"{vt=$2} $1==".text"{t=$2} $1==".rodata"{r=$2} $1==".data"{d=$2}
  $1==".bss"{b=$2} $1==".uninit"{u=$2}
  END{print vt+0, t+0, r+0, d+0, b+0, u+0}')
flash=$((vt + text + rodata + data))
static_ram=$((data + bss + uninit))
echo "flash: vector_table $vt + text $text + rodata $rodata + data $data = $flash bytes"
echo "static RAM: data $data + bss $bss + uninit $uninit = $static_ram bytes"

echo "==> stack high-water mark (painted stack) of the production firmware in the HIL run" >&2
hil=$(cargo test -q -p fog-system-tests --test firmware_qemu -- --nocapture 2>&1 | grep '^HIL:' || true)
stack=$(sed -n 's/.*stack high-water \([0-9]*\) bytes.*/\1/p' <<<"$hil")
if [ -z "$stack" ]; then
  echo "stack high-water: not measured (HIL test did not report it)"; exit 1
fi
echo "stack high-water: $stack bytes ($hil)"
ram=$((static_ram + stack))

goal() { # name value limit
  if [ "$2" -le "$3" ]; then echo "goal $1 <= $3: met ($2, $(($3 - $2)) to spare)";
  else echo "goal $1 <= $3: NOT met ($2, over by $(($2 - $3)))"; fi
}
echo
goal "flash (bytes)" "$flash" 65536
goal "RAM incl. stack, B = 512 (bytes)" "$ram" 16384
