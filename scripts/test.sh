#!/usr/bin/env bash
# Runs every test of the workspace, the AVR builds and the simavr tests
# included. Installs what it needs first (scripts/setup.sh).
set -euo pipefail
# Nothing below reads the terminal; a stray stdin (a pipe left open by the
# caller) must not reach the tools (cargo hands it to its rustc probes).
exec </dev/null
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
bash scripts/setup.sh

# Property tests draw from a fixed seed so a CI run is reproducible; set
# PROPTEST_RNG_SEED to explore other inputs.
export PROPTEST_RNG_SEED="${PROPTEST_RNG_SEED:-20261121}"
# setup.sh installed avr-gcc and simavr: the C example's AVR builds in
# tests/tests/ffi_c.rs must run here, not skip.
export KESTREL_REQUIRE_AVR=1

echo "== cargo fmt --all --check"
cargo fmt --all --check
echo "== cargo clippy --workspace --all-targets -- -D warnings"
cargo clippy --workspace --all-targets -- -D warnings
echo "== cargo doc --workspace --no-deps (broken intra-doc links are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
echo "== kestrel codegen --check (generated tables and golden files up to date)"
cargo run --quiet -p kestrel-tools -- codegen --check
echo "== cargo test --workspace (unit, integration and doc tests)"
cargo test --workspace
echo "== AVR builds"
bash scripts/avr-check.sh
echo "== fuzz smoke (every cargo-fuzz target, 2,000 runs each; the full run and its report: scripts/fuzz.sh, docs/fuzz.md)"
bash scripts/fuzz.sh --smoke
echo "== cargo package (publishable crates, each verified by building it alone from its package)"
# Verification builds each crate against a local registry of the packages
# just made, which cargo unpacks under ~/.cargo/registry/src/<hash of the
# registry's path>/ and never refreshes for the same name and version: a
# fixed target directory would verify against the sources of an earlier run.
# A new target directory per run gives a new registry path; both it and the
# unpacked copies it leaves are removed afterwards (nothing else is).
pkg_target="$(mktemp -d "${TMPDIR:-/tmp}/kestrel-package.XXXXXX")"
registry_src="${CARGO_HOME:-$HOME/.cargo}/registry/src"
before="$(ls -1 "$registry_src" 2>/dev/null || true)"
cleanup_package() {
  rm -rf "$pkg_target"
  for d in "$registry_src"/*/; do
    name="$(basename "$d")"
    if ! grep -qxF -- "$name" <<<"$before" \
       && [ -z "$(find "$d" -mindepth 1 -maxdepth 1 ! -name 'kestrel-*' -print -quit)" ]; then
      rm -rf "$d"
    fi
  done
}
trap cleanup_package EXIT
cargo package --workspace --quiet --allow-dirty --target-dir "$pkg_target" \
  --exclude kestrel-benches --exclude kestrel-tests
cleanup_package
trap - EXIT
