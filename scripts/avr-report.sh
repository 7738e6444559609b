#!/usr/bin/env bash
# The AVR cycle report: flies the example firmware hardware-in-the-loop in
# simavr (crates/tricopter/tests/hil/) for every configuration, prints the
# per-stage cycles and sizes, and ends with one JSON line:
#   {"hil_passed": true, "configs": [{"scalar": ..., "solver": ..., "kalman_cycles": {...}, ...}, ...],
#    "qp_check": [{"scalar": "f32", "solver": "qp", "start": "cold", "cycles": {...}, ...}, ...]}
# "configs": one entry per flown configuration (solver "fgm", "empc", "empc-ns2", "qp", ...);
# "qp_check": the exact MPC's whole-law cycles on the target at pseudo-random
# parameters of the whole box ("start": cold, warm along a random walk -- "walk-cold" for
# the qp16 builds, which start cold every period --, cap1: iteration cap 1), beside the flights.
# Usage: bash scripts/avr-report.sh   (from any directory)
set -uo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
KESTREL_HIL_REPORT=1 cargo test -p kestrel-tricopter --test hil -- \
  --nocapture --test-threads 2 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
passed=false
[ "$status" -eq 0 ] && passed=true
configs="$(sed -n 's/^HIL-REPORT //p' "$log" | paste -sd, -)"
qp_check="$(sed -n 's/^QP-CHECK //p' "$log" | paste -sd, -)"
echo "{\"hil_passed\": $passed, \"configs\": [${configs}], \"qp_check\": [${qp_check}]}"
