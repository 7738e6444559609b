#!/usr/bin/env bash
# The main job: everything the project can do, end to end, on the built-in
# examples. Writes its results to report/ (or the directory given as $1).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
out="${1:-report}"
mkdir -p "$out"
cargo build --release -p kestrel-tools
kestrel="$root/target/release/kestrel"
"$kestrel" --version
echo "== c2d: the double integrator at 50 Hz"
"$kestrel" c2d --model examples/double-integrator.json --ts 0.02 --out "$out/double-integrator-50hz.json"
cat "$out/double-integrator-50hz.json"
echo "main job done: results in $out/"
