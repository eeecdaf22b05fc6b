#!/usr/bin/env bash
# The system tests (fog-system-tests: the firmware under QEMU, its builds, cycle and panic
# checks) in a debug and a release run at the same time, each running its tests in
# parallel: two processes and many threads building firmware images and running QEMU at
# once, as a user's `cargo test` and `cargo test --release` would. A race between builds,
# paths, sockets or temp names fails here instead of passing by timing. Called by
# scripts/test-all.sh; extra arguments go to both runs (e.g. `--test firmware_qemu`).
set -euo pipefail
cd "$(dirname "$0")/.."

logs=$(mktemp -d "${TMPDIR:-/tmp}/fog-fw-parallel-XXXXXX")
trap 'rm -rf "$logs"' EXIT
# Build both first (cargo serialises builds of one target directory anyway): the runs then
# overlap for their whole length.
cargo test -q -p fog-system-tests --no-run "$@"
cargo test -q --release -p fog-system-tests --no-run "$@"
t0=$(date +%s)
cargo test -p fog-system-tests "$@" >"$logs/debug.log" 2>&1 &
debug=$!
cargo test --release -p fog-system-tests "$@" >"$logs/release.log" 2>&1 &
release=$!
rc_debug=0; wait "$debug" || rc_debug=$?
rc_release=0; wait "$release" || rc_release=$?
for run in debug release; do
  printf '\n--- fog-system-tests, %s run (beside the other) ---\n' "$run"
  cat "$logs/$run.log"
done
echo "fog-system-tests in parallel: debug rc $rc_debug, release rc $rc_release, $(( $(date +%s) - t0 )) s" >&2
[ "$rc_debug" -eq 0 ] && [ "$rc_release" -eq 0 ]
