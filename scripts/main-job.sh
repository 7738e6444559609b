#!/usr/bin/env bash
# The main job: the thesis workflow end to end on the built-in tricopter,
# with the `kestrel` subcommands chained: fly the four experiments, identify
# a black-box model, design the Kalman filter and the MPC problems, solve
# them explicitly and certify the fast gradient method, fly the closed loop.
# Results go to report/ (or the directory given as $1); the directory only
# appears when every step has succeeded.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
out="${1:-report}"
# Fonts for the plots, the AVR toolchain etc.
bash scripts/setup.sh >/dev/null
cargo build --release -p kestrel-tools
k="$root/target/release/kestrel"
"$k" --version

mkdir -p "$(dirname "$out")"
stage="$(mktemp -d "$(dirname "$out")/.$(basename "$out").partial.XXXXXX")"
trap 'rm -rf "$stage"' EXIT
log() { printf '\n== %s\n' "$*" | tee -a "$stage/steps.md"; }

log "1. flight experiments (section 7.1), 250 s each, seed 1"
for e in hover decoupled coupled ground; do
  "$k" simulate --experiment "$e" --seconds 250 --seed 1 --out "$stage/flight-$e.csv"
done
"$k" simulate --experiment hover --seconds 1 --seed 1 --noiseless \
  --rate-model "$stage/true-rate-model.json" --out "$stage/.discard.csv"
rm -f "$stage/.discard.csv"

log "2. black-box model from experiment 2 (section 7.4): order 8 reduced to 5"
"$k" identify --data "$stage/flight-decoupled.csv" \
  --inputs pwm1,pwm2,pwm3,servo --outputs p,q,r \
  --estimate 25.66:50.28,108.9:165.8 --validate 181:219 \
  --order 8 --reduce 5 --out "$stage/model-blackbox.json" | tee "$stage/identify-blackbox.txt"

log "3. stationary Kalman filter (section 7.5)"
"$k" kalman --model "$stage/model-blackbox.json" --q 1 --r 1e-4 \
  --out "$stage/kalman.json"

log "4. MPC problems (section 7.6): thesis-sized (N = 2, Ns = 1) and larger (N = 10, blocks 1,1,2,6)"
"$k" mpc --model "$stage/model-blackbox.json" --horizon 2 --blocks 2 \
  --terminal lq --out "$stage/problem-thesis.json"
"$k" mpc --model "$stage/model-blackbox.json" --horizon 10 --blocks 1,1,2,6 \
  --terminal lq --out "$stage/problem-larger.json"

log "5. explicit MPC of the thesis-sized problem (section 7.6.1)"
"$k" empc solve --problem "$stage/problem-thesis.json" --out "$stage/empc-solution.json"
"$k" empc export --solution "$stage/empc-solution.json" --scalar f32 --out "$stage/empc-tables.rs"

log "6. fast gradient certification (section 7.6.2)"
for p in thesis larger; do
  "$k" fgm certify --problem "$stage/problem-$p.json" --eps 1e-2 | tee "$stage/fgm-certify-$p.json"
done

log "7. closed loop on the nonlinear tricopter (section 7.7): MPC (clarabel) and the baseline PI"
for c in qp pid; do
  "$k" closed-loop --controller "$c" --noise --seed 1 --out "$stage/closed-loop-$c.csv"
done

rm -rf "$out"
mv "$stage" "$out"
trap - EXIT
echo "main job done: results in $out/"
