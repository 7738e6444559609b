#!/usr/bin/env bash
# Identification on the real flight logs (../shared/data/flight): every
# log imported with `kestrel import` at 50 Hz and at its native 500 Hz,
# then the default `kestrel identify` (automatic structure choice) with
# the first half of each airborne segment to estimate and the second half
# to validate; prints one markdown row per log and rate with the mean fit
# over p, q, r of the model, persistence and the best ARX (2-10 lags) at
# 1 and 5 steps, the simulation fit, the chosen structure and the time.
#
#   scripts/flight-logs.sh            # all logs, 50 and 500 Hz
#   RATES=50 scripts/flight-logs.sh   # 50 Hz only
#
# Environment: KESTREL (binary; default: built here in release),
# FLIGHT_DATA (default ../shared/data/flight), OUT (work directory,
# default a fresh temporary one), RATES (default "50 500"), LOGS (default
# all four), EXTRA (more flags for identify, e.g. "--time-budget 20").
# Takes about 15 s at 50 Hz and 1 minute at 500 Hz on 2 cores (each
# identify is bounded by the work budget; the 60 s safety stop is named
# in the report when it fires: on a heavily loaded machine it can, and
# the choice then depends on the load; EXTRA="--time-budget 300" gives
# the work-planned choice whatever the load).
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ -z "${KESTREL:-}" ]]; then
    cargo build --release -q -p kestrel-tools
    KESTREL=target/release/kestrel
fi
DATA=${FLIGHT_DATA:-../shared/data/flight}
OUT=${OUT:-$(mktemp -d /tmp/kestrel-flight-logs.XXXXXX)}
RATES=${RATES:-50 500}
LOGS=${LOGS:-betaflight/btfl_002.bbl crazyflie/log10 crazyflie/log15 crazyflie/log16}
mkdir -p "$OUT"

# The estimation and validation intervals: the first and second half of
# the samples of every experiment (airborne segment), `N@a:b` each.
halves() {
    awk -F, '
        NR == 1 { for (i = 1; i <= NF; i++) if ($i == "experiment") ec = i; next }
        { e = ec ? $ec : 1; if (!(e in n)) order[++ne] = e; t[e, ++n[e]] = $1 }
        END {
            for (j = 1; j <= ne; j++) {
                e = order[j]; h = int(n[e] / 2)
                if (h < 2) continue
                est = est sep j "@" t[e, 1] ":" t[e, h]
                val = val sep j "@" t[e, h + 1] ":" t[e, n[e]]
                sep = ","
            }
            print est; print val
        }' "$1"
}

# The mean column of a row of the fit table.
mean_of() {
    awk -v label="$1" 'index($0, label) == 1 { print $NF; exit }' "$2"
}

echo "| log | rate | samples (est) | model 1-step | ARX 1-step | persistence 1-step | model 5-step | ARX 5-step | persistence 5-step | model simulation | chosen | time |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for log in $LOGS; do
    name=$(basename "$log" .bbl)
    for rate in $RATES; do
        csv="$OUT/${name}_${rate}.csv"
        "$KESTREL" import "$DATA/$log" --rate "$rate" --out "$csv" --force >/dev/null 2>&1
        inputs=$(head -1 "$csv" | cut -d, -f2-5)
        { read -r est; read -r val; } < <(halves "$csv")
        report="$OUT/${name}_${rate}.txt"
        start=$(date +%s.%N)
        # shellcheck disable=SC2086
        "$KESTREL" identify --data "$csv" --inputs "$inputs" --outputs p,q,r \
            --estimate "$est" --validate "$val" --out "$OUT/${name}_${rate}.ss.json" --force \
            ${EXTRA:-} >"$report" 2>&1
        secs=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.0f", e - s }')
        samples=$(awk '/^data:/ { print $2; exit }' "$report")
        chosen=$(awk '/^chosen:/ { sub(/^chosen: /, ""); sub(/ \(score.*/, ""); print; exit }' "$report")
        echo "| $name | $rate Hz | $samples | $(mean_of "model 1-step" "$report") | $(mean_of "best ARX 1-step" "$report") | $(mean_of "persistence 1-step" "$report") | $(mean_of "model 5-step" "$report") | $(mean_of "best ARX 5-step" "$report") | $(mean_of "persistence 5-step" "$report") | $(mean_of "model simulation" "$report") | ${chosen:-(not chosen)} | ${secs} s |"
    done
done
echo "(reports and models in $OUT)"
