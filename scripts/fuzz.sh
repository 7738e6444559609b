#!/usr/bin/env bash
# Runs the cargo-fuzz targets of fuzz/ (every reader and no_std table
# validator; see docs/fuzz.md), one at a time, each for a fixed number of
# executions, and prints a table: target, executions, executions per
# second, coverage (libFuzzer's final `cov` and `ft`), corpus size and
# crashes. Exits non-zero if any target crashed (the input is left in
# fuzz/artifacts/<target>/).
#
#   scripts/fuzz.sh                  every target, 1,000,000 executions each
#   scripts/fuzz.sh --smoke          every target, 2,000 executions, unoptimised build (CI)
#   scripts/fuzz.sh --runs N ss csv_log   N executions of the targets named
#
# Needs the pinned nightly (avr/rust-toolchain.toml) and cargo-fuzz; a
# missing cargo-fuzz is installed (`cargo install cargo-fuzz --locked`).
# The full run grows fuzz/corpus/<target>/ (not committed) from the seeds
# and found inputs in fuzz/regressions/<target>/ (committed; read by
# tests/tests/fuzz_regressions.rs); --smoke starts from the seeds alone
# in a temporary folder. Found crashes, once fixed, go to
# fuzz/regressions/<target>/ with a `.expected` file (see that test).
set -euo pipefail

cd "$(dirname "$0")/.."
NIGHTLY=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' avr/rust-toolchain.toml)
TARGETS=(ss mpqp kalman empc_solution csv_log frame tree16 flash_tree fgm16 kalman16 thetas matrix_file logs)
RUNS=1000000
SMOKE=0
picked=()
while (($#)); do
    case "$1" in
        --smoke) SMOKE=1; RUNS=2000 ;;
        --runs) RUNS="$2"; shift ;;
        -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
        -*) echo "fuzz.sh: unknown option $1" >&2; exit 2 ;;
        *) picked+=("$1") ;;
    esac
    shift
done
((${#picked[@]})) && TARGETS=("${picked[@]}")

# The longest input per target: JSON files (matrix files too) up to 8 KiB (long enough for a
# short file to claim a matrix above the 32 MiB allocation limit of
# fuzz/src/lib.rs), CSV logs and parameter rows 4 KiB, binary flight logs 16 KiB (a few
# hundred records of each format), binary tables 1 KiB,
# frames 512 bytes.
max_len() {
    case "$1" in
        ss|mpqp|kalman|empc_solution|matrix_file) echo 8192 ;;
        csv_log|thetas) echo 4096 ;;
        logs) echo 16384 ;;
        frame) echo 512 ;;
        *) echo 1024 ;;
    esac
}

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "installing cargo-fuzz" >&2
    cargo +stable install cargo-fuzz --locked
fi
rustup run "$NIGHTLY" rustc --version >/dev/null 2>&1 ||
    rustup toolchain install "$NIGHTLY" --profile minimal
FUZZ=(cargo "+$NIGHTLY" fuzz)
# No sanitizer: the code under test is safe Rust; panics, overflow checks
# (debug assertions are on), aborts, the allocation limit and timeouts are
# what is caught, at about twice the speed of AddressSanitizer.
OPTS=(--sanitizer none --fuzz-dir fuzz)
# The smoke builds without optimisation: half the cold build time, and
# its few thousand runs take seconds even so.
((SMOKE)) && OPTS+=(--dev)

start=$(date +%s)
"${FUZZ[@]}" build "${OPTS[@]}" >&2

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rows=()
failed=0
for t in "${TARGETS[@]}"; do
    mkdir -p "fuzz/artifacts/$t"
    if ((SMOKE)); then corpus="$tmp/corpus-$t"; else corpus="fuzz/corpus/$t"; fi
    mkdir -p "$corpus"
    log="$tmp/$t.log"
    before=$(ls "fuzz/artifacts/$t" | wc -l)
    t0=$(date +%s)
    status=0
    "${FUZZ[@]}" run "${OPTS[@]}" "$t" "$corpus" "fuzz/regressions/$t" -- \
        -runs="$RUNS" -max_len="$(max_len "$t")" -timeout=10 -rss_limit_mb=2048 \
        -max_total_time=1800 -print_final_stats=1 \
        -artifact_prefix="fuzz/artifacts/$t/" >"$log" 2>&1 || status=$?
    secs=$(($(date +%s) - t0))
    crashes=$(($(ls "fuzz/artifacts/$t" | wc -l) - before))
    stat() { sed -n "s/^stat::$1: *//p" "$log" | tail -1; }
    execs=$(stat number_of_executed_units)
    last=$(grep -E '^#[0-9]+' "$log" | tail -1)
    cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
    ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
    corp=$(sed -n 's/.* corp: \([0-9]*\).*/\1/p' <<<"$last")
    if ((status != 0)) && ((crashes == 0)); then crashes=1; fi
    if ((crashes)); then
        failed=1
        echo "fuzz.sh: $t: crash (exit $status), see $log kept as fuzz/artifacts/$t/log.txt" >&2
        cp "$log" "fuzz/artifacts/$t/log.txt"
        grep -E 'panicked|ERROR|deadly|Test unit written|SUMMARY' "$log" | head -5 >&2 || true
    fi
    rows+=("$(printf '| %s | %s | %s | %s | %s | %s | %s | %s |' \
        "$t" "${execs:-?}" "$(stat average_exec_per_sec)" "${cov:-?}" "${ft:-?}" \
        "${corp:-?}" "$crashes" "${secs} s")")
done

echo
echo "| target | executions | exec/s | cov | ft | corpus | crashes | time |"
echo "|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
echo
echo "total $(($(date +%s) - start)) s (build included), $RUNS runs per target, $NIGHTLY, cargo-fuzz $(cargo fuzz --version 2>/dev/null | awk '{print $2}')"
exit "$failed"
