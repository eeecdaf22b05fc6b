#!/usr/bin/env bash
# Coverage-guided fuzzing (libFuzzer via libfuzzer-sys) of fog-core's decoders and identifier
# and host-sim's CSV readers: builds fuzz/ (its own cargo workspace) with plain cargo on the
# pinned stable toolchain and runs every target for a bounded time. No cargo-fuzz, no nightly:
# the SanitizerCoverage instrumentation cargo-fuzz would add is passed here as stable codegen
# flags (no AddressSanitizer: the code under test is safe Rust, `unsafe_code` is forbidden).
#
#   bash scripts/fuzz.sh                 # every target, FUZZ_SECONDS (default 20) each
#   bash scripts/fuzz.sh ecore 600       # one target, 10 minutes
#   bash scripts/fuzz.sh --minimize      # merge the inputs found (target/fuzz-new/*) into the
#                                        # committed corpora (fuzz/corpus/*), minimised
#
# New inputs found by a run go to target/fuzz-new/<target>/ (the committed corpus is only
# read); a crash is written to target/fuzz-artifacts/<target>/ and fails the script.
set -euo pipefail
cd "$(dirname "$0")/.."

TARGETS=(ecore dsp3000 csv_record identifier)
# Longest input per target (bytes): a few blocks of samples for the identifier.
declare -A MAX_LEN=([ecore]=4096 [dsp3000]=4096 [csv_record]=4096 [identifier]=16384)

host=$(rustc -vV | sed -n 's/^host: //p')
export CARGO_TARGET_DIR="${FUZZ_TARGET_DIR:-$PWD/fuzz/target}"
# One run at a time per target directory: two runs (two test-all.sh at once, or --minimize
# beside a run) would share the logs, the new inputs and the corpus being replaced.
mkdir -p "$CARGO_TARGET_DIR"
exec 9>"$CARGO_TARGET_DIR/fuzz.lock"
flock 9
# RUSTFLAGS apply only to the target crates because --target is given (build scripts and
# proc-macros are not instrumented), as cargo-fuzz does.
export RUSTFLAGS="-Cpasses=sancov-module \
 -Cllvm-args=-sanitizer-coverage-level=4 \
 -Cllvm-args=-sanitizer-coverage-inline-8bit-counters \
 -Cllvm-args=-sanitizer-coverage-pc-table \
 -Cllvm-args=-sanitizer-coverage-trace-compares \
 --cfg fuzzing -Cforce-frame-pointers=yes"
unset CARGO_ENCODED_RUSTFLAGS CARGO_BUILD_TARGET

ms() { echo $(( $(date +%s%N) / 1000000 )); }
secs() { printf '%d.%01d' $(( $1 / 1000 )) $(( $1 % 1000 / 100 )); }
t_build=$(ms)
(cd fuzz && cargo build -q --release --locked --target "$host" --bins)
bin_dir="$CARGO_TARGET_DIR/$host/release"
echo "fuzz: build $(secs $(( $(ms) - t_build ))) s" >&2

if [ "${1:-}" = "--minimize" ]; then
  for t in "${TARGETS[@]}"; do
    tmp=$(mktemp -d)
    mkdir -p "$CARGO_TARGET_DIR/fuzz-new/$t"
    "$bin_dir/$t" -merge=1 -use_counters=0 -max_len="${MAX_LEN[$t]}" "$tmp" "fuzz/corpus/$t" \
      "$CARGO_TARGET_DIR/fuzz-new/$t" >/dev/null 2>&1
    rm -rf "fuzz/corpus/$t" && mv "$tmp" "fuzz/corpus/$t"
    echo "fuzz: $t corpus minimised to $(ls "fuzz/corpus/$t" | wc -l) inputs" >&2
  done
  exit 0
fi

seconds=${FUZZ_SECONDS:-20}
if [ $# -ge 1 ]; then TARGETS=("$1"); fi
if [ $# -ge 2 ]; then seconds=$2; fi
# Targets run side by side, one per core (FUZZ_JOBS, default the cores): each still gets
# `seconds` of one core, the wall time is that of ceil(targets / jobs) runs.
jobs=${FUZZ_JOBS:-$(nproc)}
[ "$jobs" -ge 1 ] || jobs=1

# One target's run: its log, its new inputs, its crash directory; the summary line in
# $CARGO_TARGET_DIR/fuzz-$t.summary; fails on a crash.
run_target() {
  local t=$1
  local new="$CARGO_TARGET_DIR/fuzz-new/$t"
  local art="$CARGO_TARGET_DIR/fuzz-artifacts/$t"
  local log="$CARGO_TARGET_DIR/fuzz-$t.log"
  mkdir -p "$new" "$art" "fuzz/corpus/$t"
  local t0
  t0=$(ms)
  if ! "$bin_dir/$t" -max_total_time="$seconds" -max_len="${MAX_LEN[$t]}" -timeout=10 \
       -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$art/" \
       "$new" "fuzz/corpus/$t" >"$log" 2>&1; then
    { tail -n 60 "$log"; echo "fuzz: $t FAILED (log $log, crash input in $art/)"; } \
      >"$CARGO_TARGET_DIR/fuzz-$t.summary"
    return 1
  fi
  local runs cov
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1)
  printf 'fuzz: %-11s %s runs in %s s, %s, corpus %s committed + %s new\n' "$t" "$runs" \
    "$(secs $(( $(ms) - t0 )))" "$cov" "$(ls "fuzz/corpus/$t" | wc -l)" \
    "$(ls "$new" | wc -l)" >"$CARGO_TARGET_DIR/fuzz-$t.summary"
}

failed=0
for (( k = 0; k < ${#TARGETS[@]}; k += jobs )); do
  batch=("${TARGETS[@]:k:jobs}")
  pids=()
  for t in "${batch[@]}"; do
    rm -f "$CARGO_TARGET_DIR/fuzz-$t.summary"
    run_target "$t" &
    pids+=($!)
  done
  for i in "${!batch[@]}"; do
    wait "${pids[$i]}" || failed=1
    sum="$CARGO_TARGET_DIR/fuzz-${batch[$i]}.summary"
    if [ -f "$sum" ]; then
      cat "$sum" >&2
    else
      echo "fuzz: ${batch[$i]} FAILED before it ran (log $CARGO_TARGET_DIR/fuzz-${batch[$i]}.log)" >&2
      failed=1
    fi
  done
done
exit "$failed"
