#!/usr/bin/env bash
# The main job: the thesis workflow end to end on the built-in tricopter,
# written by `kestrel pipeline` as report/ (or the directory given as $1):
# report.md with every table, CSV logs and traces, models (kestrel.ss.v1),
# MPC problems (kestrel.mpqp.v1), SVG plots and firmware tables. The
# directory only appears when every step has succeeded. Further arguments
# go to `kestrel pipeline` (e.g. --config my.toml, --quick). Run again, it
# replaces the report it wrote before (`--force`: only a kestrel report that
# holds nothing but its own files is ever replaced; anything else is refused).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
out="${1:-report}"
shift || true
# Fonts for the plots, OpenBLAS for clarabel's SDP, the AVR toolchain etc.
bash scripts/setup.sh >/dev/null
cargo build --release -p kestrel-tools
k="$root/target/release/kestrel"
"$k" --version
"$k" pipeline --out "$out" --force "$@"
echo "main job done: results in $out/ (start with $out/report.md)"
