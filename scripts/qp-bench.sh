#!/usr/bin/env bash
# kestrel-qp against DAQP's C core, qpOASES, TinyMPC, kestrel-fgm and
# clarabel on the same problems and parameters, in one run, one table
# (issue 24; BENCHMARKS.md "Exact MPC on the host"). Not part of CI (it
# downloads the three libraries' sources from PyPI).
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
# qpOASES: PyPI has no `qpoases` package; the sdist of `cmeel-qpoases`
# (the cmeel packaging of qpOASES 3.2.2; version and sha256 pinned below)
# carries qpOASES's unmodified source tree in qpOASES/ (plus a CMake
# version patch, cmeel.patch, not needed here). Fetched into
# target/qpoases/ (or QPOASES_SRC, a directory holding include/ and src/),
# compiled with benches/qpoases/qpoases_bench.cpp by g++ with the flags of
# its make_linux.mk minus warnings and -fPIC (-O3 -DLINUX -DSOLVER_NONE
# -D__NO_COPYRIGHT__; its own BLAS/LAPACK replacements, no -march=native).
#
# TinyMPC: the sdist of `tinympc` 0.0.8 (pinned below) carries the C++
# library in tinympc/TinyMPC/src/tinympc/ and the Eigen it is built with in
# tinympc/TinyMPC/include/Eigen. Fetched into target/tinympc/ (or
# TINYMPC_SRC, the TinyMPC directory), its admm.cpp, tiny_api.cpp and
# rho_benchmark.cpp copied to $OUT/tinympc-src with one line removed (the
# `std::cout << "Solver converged in " ...` of solve(), a print per
# solve), compiled with benches/tinympc/tinympc_bench.cpp by g++ -std=c++17
# -O3 -DNDEBUG (CMake's Release flags; no -march=native). The qpOASES and
# TinyMPC harnesses (about 1 minute of g++ each) are rebuilt only when
# missing or older than their harness source: delete $OUT/qpoases_bench or
# $OUT/tinympc_bench to force it (DAQP's is rebuilt every run).
#
# The run fails (exit 1) if DAQP's, qpOASES's, clarabel's or kestrel-qp's
# warm solution differs from kestrel-qp's cold f64 one by more than 1e-9
# relative, or any of them fails: the active-set solvers must solve the
# same QP. TinyMPC's deviation is reported, not checked (ADMM, tolerances).
#
# Environment: SAMPLES (default 10000), CC (default gcc), CXX (default
# g++), DAQP_SRC, QPOASES_SRC, TINYMPC_SRC, TINYMPC_RHO (default: the
# example's, 0.1), OUT (work directory, default target/qp-bench).
# Takes about 3 minutes after the builds (the libraries' builds about 2).
set -euo pipefail
cd "$(dirname "$0")/.."
DAQP_VERSION=0.11.0
DAQP_SHA256=2f27baf18d2acca14186498e651b34e0bed455627e777d3fd8ba655e7e40f920
QPOASES_VERSION=3.2.2
QPOASES_SHA256=19048cb5a7985061aa2781ce4b2400e8d5b27bb01604056a76759d4b02660792
TINYMPC_VERSION=0.0.8
TINYMPC_SHA256=4cdac9e99af45d59ecbb4f8df6e8f46de89be1807c62eb877d1a46b8542513b1
SAMPLES=${SAMPLES:-10000}
CC=${CC:-gcc}
CXX=${CXX:-g++}
OUT=${OUT:-target/qp-bench}
mkdir -p "$OUT" target/daqp target/qpoases target/tinympc

# fetch <package> <version> <sha256> <dir> <archive>: the pinned sdist,
# downloaded by pip once (its build dependencies as wheels, only to read
# its metadata; nothing is installed), checked and unpacked into <dir>.
fetch() {
    local tarball=$4/$5
    if [[ ! -f "$tarball" ]]; then
        pip download "$1==$2" --no-binary "$1" --no-deps -d "$4" >&2
    fi
    echo "$3  $tarball" | sha256sum -c - >&2
    tar -xzf "$tarball" -C "$4"
}

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

if [[ -z "${QPOASES_SRC:-}" ]]; then
    QPOASES_SRC=target/qpoases/cmeel_qpoases-$QPOASES_VERSION/qpOASES
    if [[ ! -d "$QPOASES_SRC/src" ]]; then
        fetch cmeel-qpoases "$QPOASES_VERSION" "$QPOASES_SHA256" target/qpoases \
            "cmeel_qpoases-$QPOASES_VERSION.tar.gz"
    fi
fi
if [[ -z "${TINYMPC_SRC:-}" ]]; then
    TINYMPC_SRC=target/tinympc/tinympc-$TINYMPC_VERSION/tinympc/TinyMPC
    if [[ ! -d "$TINYMPC_SRC/src" ]]; then
        fetch tinympc "$TINYMPC_VERSION" "$TINYMPC_SHA256" target/tinympc \
            "tinympc-$TINYMPC_VERSION.tar.gz"
    fi
fi

"$CC" -O3 -fassociative-math -fno-signed-zeros -fno-trapping-math \
    -I "$DAQP_SRC/csrc/include" -o "$OUT/daqp_bench" \
    benches/daqp/daqp_bench.c "$DAQP_SRC"/csrc/src/*.c -lm
if [[ ! -x "$OUT/qpoases_bench" || benches/qpoases/qpoases_bench.cpp -nt "$OUT/qpoases_bench" || benches/harness/bench_io.h -nt "$OUT/qpoases_bench" ]]; then
    "$CXX" -O3 -DLINUX -DSOLVER_NONE -D__NO_COPYRIGHT__ -I "$QPOASES_SRC/include" \
        -o "$OUT/qpoases_bench" benches/qpoases/qpoases_bench.cpp "$QPOASES_SRC"/src/*.cpp -lm
fi
if [[ ! -x "$OUT/tinympc_bench" || benches/tinympc/tinympc_bench.cpp -nt "$OUT/tinympc_bench" || benches/harness/bench_io.h -nt "$OUT/tinympc_bench" ]]; then
    mkdir -p "$OUT/tinympc-src"
    cp "$TINYMPC_SRC"/src/tinympc/*.cpp "$TINYMPC_SRC"/src/tinympc/*.hpp "$OUT/tinympc-src/"
    sed -i '/std::cout << "Solver converged in "/d' "$OUT/tinympc-src/admm.cpp"
    "$CXX" -std=c++17 -O3 -DNDEBUG -I "$OUT/tinympc-src" -I "$TINYMPC_SRC/include/Eigen" \
        -o "$OUT/tinympc_bench" benches/tinympc/tinympc_bench.cpp \
        "$OUT"/tinympc-src/{admm,tiny_api,rho_benchmark}.cpp
fi

cargo build --release -q -p kestrel-benches --example qp_compare
echo "host: $(uname -m), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
echo "gcc: $("$CC" --version | head -1); g++: $("$CXX" --version | head -1); rustc: $(rustc --version)" >&2
target/release/examples/qp_compare --samples "$SAMPLES" --daqp "$OUT/daqp_bench" \
    --qpoases "$OUT/qpoases_bench" --tinympc "$OUT/tinympc_bench" \
    ${TINYMPC_RHO:+--rho "$TINYMPC_RHO"} --dir "$OUT"
