/*
 * Times DAQP's C core on the problems written by kestrel-benches' example
 * `qp_compare` (see scripts/qp-bench.sh). No Python anywhere: DAQP's C
 * sources (the `daqp` sdist's csrc/, version pinned in the script) are
 * compiled together with this file.
 *
 * Input (text, whitespace separated; `inf`/`-inf` allowed):
 *   name n m sets
 *   H (n*n, row-major) G (m*n, row-major)
 *   per set: label count, then per sample:
 *     q (n) l (m) u (m) lb (n) ub (n) z (n: kestrel-qp's solution) iterations
 * A set labelled `cold` is solved from the empty working set every time
 * (daqp_deactivate_constraints before the solve), any other set warm (DAQP
 * keeps its working set and its LDL' factor from the previous solve).
 *
 * Timed per solve with clock_gettime(CLOCK_MONOTONIC): copy q and the
 * bounds into the problem, daqp_update_ldp(v | d), (cold: reset the working
 * set), daqp_solve (which copies x out). Output, one line per set:
 *   daqp <name> <label> <count> <median_ns> <p99_ns> <max_ns> <mean_iter>
 *        <max_iter> <max_rel_dev_from_kestrel_qp> <failures>
 * and at the end `timer <ns>`: the median of an empty timed interval.
 * Iterations are DAQP's own count (res.iter).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "api.h"
#include "utils.h"
#include "constants.h"
#include "types.h"

#include "../harness/bench_io.h"

static double *read_vec(FILE *f, int len) {
    double *v = calloc(len > 0 ? (size_t)len : 1, sizeof(double));
    bench_read_into(f, v, len, "daqp_bench");
    return v;
}

static double clamp_inf(double v) {
    if (v >= DAQP_INF) return DAQP_INF;
    if (v <= -DAQP_INF) return -DAQP_INF;
    return v;
}

static int cmp_long(const void *a, const void *b) {
    long x = *(const long *)a, y = *(const long *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    FILE *f = bench_open_input(argc, argv, "daqp_bench", "<problems.txt>");
    char name[256];
    int n, m, sets;
    while (fscanf(f, "%255s %d %d %d", name, &n, &m, &sets) == 4) {
        double *h = read_vec(f, n * n);
        double *g = read_vec(f, m * n);
        int mt = n + m; /* DAQP: the n simple bounds first, then the rows */
        double *fv = calloc(n, sizeof(double));
        double *bu = calloc(mt, sizeof(double));
        double *bl = calloc(mt, sizeof(double));
        double *x = calloc(n, sizeof(double));
        double *lam = calloc(mt, sizeof(double));
        DAQPProblem qp = {n, mt, n, h, fv, g, bu, bl, NULL, NULL, 0, 0};
        for (int i = 0; i < mt; i++) {
            bu[i] = DAQP_INF;
            bl[i] = -DAQP_INF;
        }
        DAQPWorkspace *work = calloc(1, sizeof(DAQPWorkspace));
        allocate_daqp_settings(work);
        daqp_default_settings(work->settings);
        /* The tolerances of kestrel-qp's defaults (DAQP's default
           primal_tol is 1e-6; its dual_tol is 1e-12 already). */
        work->settings->primal_tol = 1e-10;
        work->settings->dual_tol = 1e-12;
        if (setup_daqp(&qp, work, NULL) < 0) {
            fprintf(stderr, "daqp_bench: setup failed for %s\n", name);
            return 1;
        }
        for (int s = 0; s < sets; s++) {
            char label[64];
            int count;
            if (fscanf(f, "%63s %d", label, &count) != 2 || count <= 0) {
                fprintf(stderr, "daqp_bench: malformed set header\n");
                return 2;
            }
            int cold = strcmp(label, "cold") == 0;
            /* q, l, u, lb, ub, z, iterations of each sample */
            int per = 4 * n + 2 * m + 1;
            double *all = read_vec(f, count * per);
            long *ns = calloc(count, sizeof(long));
            long iter_sum = 0;
            int iter_max = 0, failures = 0;
            double worst = 0.0;
            /* The working set of the previous problem or set is dropped. */
            daqp_deactivate_constraints(work);
            for (int k = 0; k < count; k++) {
                const double *smp = all + (size_t)k * per;
                const double *q = smp, *l = smp + n, *u = smp + n + m;
                const double *lb = smp + n + 2 * m, *ub = smp + 2 * n + 2 * m;
                const double *z = smp + 3 * n + 2 * m;
                DAQPResult res;
                memset(&res, 0, sizeof res);
                res.x = x;
                res.lam = lam;
                long t0 = bench_now_ns();
                memcpy(fv, q, n * sizeof(double));
                for (int i = 0; i < n; i++) {
                    bl[i] = clamp_inf(lb[i]);
                    bu[i] = clamp_inf(ub[i]);
                }
                for (int j = 0; j < m; j++) {
                    bl[n + j] = clamp_inf(l[j]);
                    bu[n + j] = clamp_inf(u[j]);
                }
                if (cold) daqp_deactivate_constraints(work);
                int flag = daqp_update_ldp(DAQP_UPDATE_v | DAQP_UPDATE_d, work, &qp);
                if (flag >= 0) daqp_solve(&res, work);
                long t1 = bench_now_ns();
                ns[k] = t1 - t0;
                if (flag < 0 || res.exitflag != DAQP_EXIT_OPTIMAL) {
                    failures++;
                    continue;
                }
                iter_sum += res.iter;
                if (res.iter > iter_max) iter_max = res.iter;
                double scale = 1.0, dev = 0.0;
                for (int i = 0; i < n; i++)
                    if (fabs(z[i]) + 1.0 > scale) scale = fabs(z[i]) + 1.0;
                for (int i = 0; i < n; i++) {
                    double d = fabs(x[i] - z[i]) / scale;
                    if (d > dev) dev = d;
                }
                if (dev > worst) worst = dev;
            }
            qsort(ns, count, sizeof(long), cmp_long);
            long p99 = ns[(size_t)((count - 1) * 0.99)];
            printf("daqp %s %s %d %ld %ld %ld %.3f %d %.3e %d\n", name, label, count,
                   ns[count / 2], p99, ns[count - 1],
                   (double)iter_sum / (count - failures > 0 ? count - failures : 1), iter_max,
                   worst, failures);
            fflush(stdout);
            free(all);
            free(ns);
        }
        free_daqp_workspace(work);
        free_daqp_ldp(work);
        free(work);
        free(h);
        free(g);
        free(fv);
        free(bu);
        free(bl);
        free(x);
        free(lam);
    }
    fclose(f);
    /* The clock's own cost: the median of an empty timed interval. */
    {
        enum { K = 100000 };
        static long e[K];
        for (int k = 0; k < K; k++) {
            long t0 = bench_now_ns();
            e[k] = bench_now_ns() - t0;
        }
        qsort(e, K, sizeof(long), cmp_long);
        printf("timer %ld\n", e[K / 2]);
    }
    return 0;
}
