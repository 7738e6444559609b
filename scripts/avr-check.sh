#!/usr/bin/env bash
# Builds the no_std crates for the ATmega2560 (avr-none) with the pinned nightly.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root/avr"   # picks up avr/rust-toolchain.toml and avr/.cargo/config.toml
# The no_std crates that must build for the AVR.
crates=(kestrel-core kestrel-avr-rt kestrel-kalman kestrel-tricopter-model kestrel-fgm kestrel-empc kestrel-qp)
for c in "${crates[@]}"; do
  echo "== avr-none build: $c"
  cargo build --release --manifest-path "$root/Cargo.toml" -p "$c" --no-default-features
done
# The C ABI as a staticlib for avr-gcc firmware: a no_std staticlib must
# abort on panic (the workspace's release profile unwinds on the host).
echo "== avr-none staticlib: kestrel-ffi"
CARGO_PROFILE_RELEASE_PANIC=abort cargo build --release --manifest-path "$root/Cargo.toml" -p kestrel-ffi --no-default-features --features panic-handler
echo "avr-check: ${#crates[@]} crate(s) and the kestrel-ffi staticlib built for avr-none"
