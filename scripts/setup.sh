#!/usr/bin/env bash
# Installs everything the build and tests need on a fresh Debian machine:
# Debian packages (AVR toolchain, simavr and the libraries avr-tester needs),
# rustfmt and clippy for the stable host toolchain, and the pinned nightly
# with rust-src for the AVR target. Safe to run again: it skips what is there.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"

packages=(gcc-avr avr-libc binutils-avr simavr libelf-dev libclang-dev clang pkg-config zlib1g-dev libzstd-dev fonts-dejavu-core libopenblas-dev libgfortran-12-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

rustup component add rustfmt clippy >/dev/null 2>&1 || rustup component add rustfmt clippy
nightly="$(sed -n 's/^channel *= *"\(.*\)"/\1/p' "$root/avr/rust-toolchain.toml")"
if ! rustup run "$nightly" rustc --print sysroot >/dev/null 2>&1 \
   || [ ! -d "$(rustup run "$nightly" rustc --print sysroot)/lib/rustlib/src/rust/library" ]; then
  echo "setup: installing $nightly with rust-src"
  rustup toolchain install "$nightly" --profile minimal --component rust-src
fi
echo "setup: ok (stable $(rustc --version | cut -d' ' -f2), AVR nightly $nightly)"
