#!/usr/bin/env bash
# Firmware budget: instructions per sample (QEMU mps2-an386 under -icount, SysTick calibrated
# with a counted loop) and, from the instruction trace of the same run, estimated cycles per
# stage, per sample and per function on a Cortex-M4F at 168 MHz (fw-cycles: TRM timings, flash
# wait states and ART as stated assumptions); memory per board: flash and static RAM of the mps2-an386 production
# ELF, the STM32F407 ELF and its QEMU variant (qemu-netduinoplus2), the stack high-water mark
# of mps2-an386 and of the STM32 build from their hardware-in-the-loop runs. Prints the table
# and each goal's distance (RAM incl. stack <= 16 KiB, and with >= 1 KiB to spare).
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

echo "==> instructions per sample (qemu-system-arm -icount shift=6,align=off,sleep=off) and, from the" >&2
echo "    instruction trace of that same run, estimated Cortex-M4F cycles (fw-cycles, tests/src/cycles.rs)" >&2
# One QEMU run: the firmware prints its table (INSTRUCTIONS, from -icount) and the trace plugin
# (scripts/qemu-trace/fogtrace.c) records every executed address; fw-cycles costs them with
# the Cortex-M4 TRM timings and the STM32F407 flash/ART assumptions it names, and fails when
# its instruction counts per window differ from the firmware's.
cargo build -q --release -p fog-system-tests --bin fw-cycles
fw_cycles=${CARGO_TARGET_DIR:-target}/release/fw-cycles
table=$(timeout 300 "$fw_cycles" "$budget_elf")
echo "$table"
if [ -n "$clock_mhz" ]; then
  # The firmware's whole-pipeline row (the first): "| whole pipeline (decode+stage+record) | sample | MEAN | MAX |".
  read -r mean worst < <(awk -F'|' '/whole pipeline \(decode\+stage/ {gsub(/ /, "", $4); gsub(/ /, "", $5); print $4, $5; exit}' <<<"$table")
  awk -v m="$mean" -v w="$worst" -v c="$clock_mhz" -v r="$rate_hz" 'BEGIN {
    avail = c * 1e6 / r;
    printf "budget at %d MHz, %d Hz: %d instructions per sample available; pipeline mean %.1f (%.2f %%), worst sample %.1f (%.2f sample periods); INSTRUCTIONS, not cycles\n", c, r, avail, m, 100 * m / avail, w, w / avail }'
  # fw-cycles' cycle table row: "| whole pipeline ... | sample | I / I | LOW / LOW | EST / EST | HIGH / HIGH |".
  read -r est_mean est_worst high_worst < <(awk -F'|' '/whole pipeline \(decode\+stage/ && $4 ~ /\// {split($6, e, "/"); split($7, h, "/"); print e[1]+0, e[2]+0, h[2]+0; exit}' <<<"$table")
  awk -v m="$est_mean" -v w="$est_worst" -v h="$high_worst" -v c="$clock_mhz" -v r="$rate_hz" 'BEGIN {
    avail = c * 1e6 / r;
    printf "budget at %d MHz, %d Hz: %d cycles per sample available; ESTIMATED CYCLES (fw-cycles, model estimate): pipeline mean %.1f (%.2f %%), worst sample %d (%.2f %%); worst in model high %d (%.2f %%)\n", c, r, avail, m, 100 * m / avail, w, 100 * w / avail, h, 100 * h / avail }'
fi

echo
echo "==> memory per board, from size -A (flash = vector table + text + rodata + data; static RAM = data + bss + uninit)"
stm32_elf=$fw/target/stm32/thumbv7em-none-eabihf/release/fog-firmware
netduino_elf=$fw/target/netduino/thumbv7em-none-eabihf/release/fog-firmware
(cd $fw && env -u RUSTFLAGS cargo build -q --release --no-default-features --features board-stm32f407 --target-dir target/stm32)
(cd $fw && env -u RUSTFLAGS cargo build -q --release --no-default-features --features qemu-netduinoplus2 --target-dir target/netduino)
# memory NAME ELF: prints the line and sets flash and static_ram.
memory() {
  read -r vt text rodata data bss uninit < <(size -A "$2" | awk '
    $1==".vector_table"{vt=$2} $1==".text"{t=$2} $1==".rodata"{r=$2} $1==".data"{d=$2}
    $1==".bss"{b=$2} $1==".uninit"{u=$2}
    END{print vt+0, t+0, r+0, d+0, b+0, u+0}')
  flash=$((vt + text + rodata + data))
  static_ram=$((data + bss + uninit))
  echo "$1: flash $flash bytes (vector_table $vt + text $text + rodata $rodata + data $data); static RAM $static_ram bytes (data $data + bss $bss + uninit $uninit)"
}

echo "==> stack high-water marks (painted stack) from the HIL runs: mps2-an386 and the STM32 build on netduinoplus2" >&2
hil_out=$(cargo test -q -p fog-system-tests --test firmware_qemu -- --nocapture --test-threads=1 \
  firmware_under_qemu_matches_host_bit_for_bit stm32_build_under_netduinoplus2_matches_host_bit_for_bit 2>&1 || true)
# libtest's progress dots may precede a line: match anywhere.
hil=$(grep -o 'HIL: .*' <<<"$hil_out" || true)
hil_stm32=$(grep -o 'HIL netduinoplus2: .*' <<<"$hil_out" || true)
stack=$(sed -n 's/.*stack high-water \([0-9]*\) bytes.*/\1/p' <<<"$hil")
stack_stm32=$(sed -n 's/.*stack high-water \([0-9]*\) bytes.*/\1/p' <<<"$hil_stm32")
if [ -z "$stack" ] || [ -z "$stack_stm32" ]; then
  echo "stack high-water: not measured (a HIL test did not report it)"; exit 1
fi

goal() { # name value limit
  if [ "$2" -le "$3" ]; then echo "goal $1 <= $3: met ($2, $(($3 - $2)) to spare)";
  else echo "goal $1 <= $3: NOT met ($2, over by $(($2 - $3)))"; fi
}
spare() { # name value limit wanted-spare
  if [ $(($3 - $2)) -ge "$4" ]; then echo "goal $1 with >= $4 B to spare: met ($(($3 - $2)) to spare)";
  else echo "goal $1 with >= $4 B to spare: NOT met ($(($3 - $2)) to spare)"; fi
}

echo
memory "mps2-an386 (production ELF, $elf)" "$elf"
echo "mps2-an386: stack high-water $stack bytes in the HIL run ($hil)"
ram=$((static_ram + stack))
echo "mps2-an386: RAM incl. stack $ram bytes"
goal "mps2-an386 flash (bytes)" "$flash" 65536
goal "mps2-an386 RAM incl. stack, B = 512 (bytes)" "$ram" 16384
spare "mps2-an386 RAM incl. stack" "$ram" 16384 1024

echo
memory "stm32f407 (board build, $stm32_elf)" "$stm32_elf"
flash_board=$flash
ram_board=$((static_ram + stack_stm32))
memory "stm32f407 qemu-netduinoplus2 (the same build minus clock tree and I2C1, $netduino_elf)" "$netduino_elf"
ram_variant=$((static_ram + stack_stm32))
echo "stm32 (qemu-netduinoplus2): stack high-water $stack_stm32 bytes in the HIL run ($hil_stm32)"
echo "stm32f407 board build: RAM incl. stack $ram_board bytes = its static RAM + the stack measured on the QEMU variant (the board build itself has never run: its I2C1 reads and clock set-up are not in the measured stack)"
echo "stm32 qemu-netduinoplus2: RAM incl. stack $ram_variant bytes (measured)"
goal "stm32f407 flash (bytes)" "$flash_board" 65536
goal "stm32f407 RAM incl. stack, B = 512 (bytes)" "$ram_board" 16384
spare "stm32f407 RAM incl. stack" "$ram_board" 16384 1024
