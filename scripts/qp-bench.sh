#!/usr/bin/env bash
# kestrel-qp against DAQP's C core, kestrel-fgm and clarabel on the same
# problems and parameters, in one run, one table (issue 24; BENCHMARKS.md
# "Exact MPC on the host"). Not part of CI (it downloads DAQP's sources).
#
#   scripts/qp-bench.sh              # 10^4 theta per problem and start
#   SAMPLES=2000 scripts/qp-bench.sh
#
# DAQP: the sources of the `daqp` package on PyPI (version and sha256
# pinned below; the sdist carries the C core in csrc/) are fetched once
# with `pip download` into target/daqp/ (or taken from DAQP_SRC, a
# directory holding csrc/), and compiled with the harness
# benches/daqp/daqp_bench.c by gcc with the flags of the package's own
# build (-O3 -fassociative-math -fno-signed-zeros -fno-trapping-math;
# no -march=native: the Rust side is built for the default x86-64 target
# too). No Python runs in the timed path: the harness is a C program that
# reads the problems and parameters the Rust example writes.
#
# The run fails (exit 1) if DAQP's, clarabel's or kestrel-qp's warm
# solution differs from kestrel-qp's cold f64 one by more than 1e-9
# relative, or any of them fails: both active-set solvers must solve the
# same QP.
#
# Environment: SAMPLES (default 10000), CC (default gcc), DAQP_SRC,
# OUT (work directory, default target/qp-bench).
# Takes about 1 minute after the build.
set -euo pipefail
cd "$(dirname "$0")/.."
DAQP_VERSION=0.11.0
DAQP_SHA256=2f27baf18d2acca14186498e651b34e0bed455627e777d3fd8ba655e7e40f920
SAMPLES=${SAMPLES:-10000}
CC=${CC:-gcc}
OUT=${OUT:-target/qp-bench}
mkdir -p "$OUT" target/daqp

if [[ -z "${DAQP_SRC:-}" ]]; then
    DAQP_SRC=target/daqp/daqp-$DAQP_VERSION
    if [[ ! -d "$DAQP_SRC/csrc" ]]; then
        tarball=target/daqp/daqp-$DAQP_VERSION.tar.gz
        if [[ ! -f "$tarball" ]]; then
            # The sdist (pip prepares its metadata in an isolated
            # environment with Cython; nothing is installed).
            pip download "daqp==$DAQP_VERSION" --no-binary :all: --no-deps \
                -d target/daqp >&2
        fi
        echo "$DAQP_SHA256  $tarball" | sha256sum -c - >&2
        tar -xzf "$tarball" -C target/daqp
    fi
fi

"$CC" -O3 -fassociative-math -fno-signed-zeros -fno-trapping-math \
    -I "$DAQP_SRC/csrc/include" -o "$OUT/daqp_bench" \
    benches/daqp/daqp_bench.c "$DAQP_SRC"/csrc/src/*.c -lm

cargo build --release -q -p kestrel-benches --example qp_compare
echo "host: $(uname -m), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
echo "gcc: $("$CC" --version | head -1); rustc: $(rustc --version)" >&2
target/release/examples/qp_compare --samples "$SAMPLES" --daqp "$OUT/daqp_bench" --dir "$OUT"
