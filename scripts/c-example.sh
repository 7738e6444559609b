#!/usr/bin/env bash
# Builds and runs kestrel's C example on the host (cc, examples/c) and for
# the ATmega2560 (avr-gcc, avr/c-example, run in simavr), then the test that
# compares both with the Rust library (tests/tests/ffi_c.rs: 10^4 random
# inputs bit for bit on the host; every period in simavr) and prints the
# AVR's cycle figures, flash and RAM.
set -euo pipefail
exec </dev/null
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"

echo "== host: examples/c (kestrel-ffi staticlib, kestrel export --lang c, cc)"
make --no-print-directory -C examples/c
printf '0.1 -0.2 0.05  0 0 0  1500\n0.12 -0.18 0.04  1 -1 0.5  1500\n-\n' | target/c-example/rate_loop

if command -v avr-gcc >/dev/null && command -v simavr >/dev/null; then
  echo "== ATmega2560: avr/c-example (avr-gcc, kestrel-ffi for avr-none) in simavr"
  for build in f32 q16 empc-f32 empc-q16; do
    law=fgm scalar=$build
    if [ "${build#empc-}" != "$build" ]; then law=empc scalar=${build#empc-}; fi
    echo "-- $law $scalar"
    make --no-print-directory -s -C avr/c-example LAW=$law SCALAR=$scalar >/dev/null
    avr-size avr/target/c-example/kestrel-c-example-$build.elf | tail -1
    simavr -m atmega2560 -f 16000000 avr/target/c-example/kestrel-c-example-$build.elf 2>&1 \
      | sed 's/\x1b\[[0-9;]*m//g' | grep -E '^(INIT|E FAIL|END)|^P (0|100|150|201|250|299) '
  done
else
  echo "== ATmega2560: skipped (avr-gcc or simavr not installed)"
fi

echo "== cargo test -p kestrel-tests --test ffi_c (C against the Rust library)"
cargo test --quiet -p kestrel-tests --test ffi_c -- --nocapture 2>&1 \
  | grep -E 'equal bit for bit|C on the ATmega2560|C-AVR-REPORT|skipped|failure|test result|panicked'
