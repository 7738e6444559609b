/*
 * Input and timing shared by the C and C++ harnesses of scripts/qp-bench.sh
 * (benches/daqp, benches/qpoases, benches/tinympc): each reads the text file
 * the Rust example `qp_compare` writes and times each solve with
 * clock_gettime(CLOCK_MONOTONIC), as the Rust side does.
 */
#ifndef KESTREL_BENCH_IO_H
#define KESTREL_BENCH_IO_H

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

/* Reads `len` numbers into `v`; on malformed or missing input, says so
 * (naming the harness `prog`) and exits with status 2. */
static inline void bench_read_into(FILE *f, double *v, int len, const char *prog) {
    for (int i = 0; i < len; i++) {
        if (fscanf(f, "%lf", &v[i]) != 1) {
            fprintf(stderr, "%s: malformed input\n", prog);
            exit(2);
        }
    }
}

/* CLOCK_MONOTONIC in nanoseconds. */
static inline long bench_now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (long)t.tv_sec * 1000000000L + t.tv_nsec;
}

/* Opens the one input file the harness takes (`usage` names it); exits with
 * status 2 and a usage line or the system's error otherwise. */
static inline FILE *bench_open_input(int argc, char **argv, const char *prog, const char *usage) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s %s\n", prog, usage);
        exit(2);
    }
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        perror(argv[1]);
        exit(2);
    }
    return f;
}

#endif
