#!/usr/bin/env bash
# Runs the host unit tests of the no_std crates whose Rust has `unsafe`
# outside AVR assembly under Miri (undefined behaviour: out-of-bounds or
# misaligned accesses, invalid values, aliasing violations, uninitialised
# reads, leaks) and prints the figures: crate, tests passed, failed,
# ignored, wall time. Exits non-zero on a failure or a Miri error.
#
#   scripts/miri.sh                  kestrel-avr-rt's library tests
#   PROPTEST_CASES=64 scripts/miri.sh    more cases per property test
#
# kestrel-avr-rt is the one no_std crate with `unsafe`; most of it is AVR
# assembly behind `cfg(target_arch = "avr")`, which the host build (and so
# Miri) never compiles. What Miri checks is the host code: the slice
# reinterpretations of `RtScalar::as_q16_bits`/`from_q16_bits`/
# `as_f32_bits` (Q16Mac, Fixed, f32 as i32) used by the Kalman and
# explicit-MPC kernels, and every kernel's safe code (the bounds checks,
# table reads of `progmem`, the frame decoder). The script warns if another
# crate's src/ has gained `unsafe`.
#
# Property tests run PROPTEST_CASES (default 8) cases each instead of 256
# (Miri interprets about 1000x slower than native code); the environment is
# passed explicitly, so Miri's isolation stays on (no host clock, files or
# randomness). Needs the pinned nightly (avr/rust-toolchain.toml) with the
# miri component (added if missing).
set -euo pipefail

cd "$(dirname "$0")/.."
NIGHTLY=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' avr/rust-toolchain.toml)
CRATES=(kestrel-avr-rt)
export PROPTEST_CASES="${PROPTEST_CASES:-8}"
export PROPTEST_DISABLE_FAILURE_PERSISTENCE=1
export MIRIFLAGS="${MIRIFLAGS:-} -Zmiri-env-forward=PROPTEST_CASES -Zmiri-env-forward=PROPTEST_DISABLE_FAILURE_PERSISTENCE"

case "${1:-}" in
    -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
    "") ;;
    *) echo "miri.sh: unknown argument $1" >&2; exit 2 ;;
esac

if ! rustup component list --toolchain "$NIGHTLY" --installed | grep -q '^miri'; then
    rustup component add miri --toolchain "$NIGHTLY"
fi
cargo "+$NIGHTLY" miri setup >/dev/null

# A crate other than those above with `unsafe` in its sources is not checked.
for dir in crates/*/; do
    name=$(sed -n 's/^name *= *"\(.*\)"/\1/p' "$dir/Cargo.toml" | head -1)
    [[ " ${CRATES[*]} " == *" $name "* ]] && continue
    if grep -rqE '\bunsafe\b' "$dir/src" 2>/dev/null; then
        echo "miri.sh: warning: $name has unsafe code and is not in CRATES" >&2
    fi
done

status=0
rows=()
for crate in "${CRATES[@]}"; do
    log=$(mktemp)
    start=$(date +%s)
    if ! cargo "+$NIGHTLY" miri test -p "$crate" --lib 2>&1 | tee "$log"; then
        status=1
    fi
    secs=$(($(date +%s) - start))
    line=$(grep -E '^test result:' "$log" | tail -1 || true)
    num() { sed -n "s/.* \([0-9]*\) $1.*/\1/p" <<<"$line"; }
    rows+=("$(printf '%-16s %7s %7s %8s %8ss' "$crate" "$(num passed)" "$(num failed)" "$(num ignored)" "$secs")")
    [[ -n "$line" ]] || status=1
    rm -f "$log"
done

echo
printf '%-16s %7s %7s %8s %9s\n' crate passed failed ignored time
printf '%s\n' "${rows[@]}"
echo "(Miri $("cargo" "+$NIGHTLY" miri --version 2>/dev/null | head -1), PROPTEST_CASES=$PROPTEST_CASES)"
exit $status
