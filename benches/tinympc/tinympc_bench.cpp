/*
 * Times TinyMPC (ADMM on the uncondensed MPC problem, Riccati-cached
 * primal step) on the problem written by kestrel-benches' example
 * `qp_compare` (see scripts/qp-bench.sh). No Python anywhere: TinyMPC's
 * C++ library (the `tinympc` sdist's tinympc/TinyMPC/src/tinympc/, with
 * the Eigen it ships, version pinned in the script) is compiled together
 * with this file.
 *
 * Input (text, whitespace separated; `inf`/`-inf` allowed):
 *   name nx nu N rho            (N: TinyMPC's knot points = horizon + 1)
 *   A (nx*nx, row-major) B (nx*nu, row-major) Q (nx: diagonal) R (nu)
 *   configs, then per config: label abs_tol max_iter
 *   sets, then per set: label count, then per sample:
 *     x0 (nx) u_min (nu*(N-1), step by step) u_max (same)
 *     z (nu*(N-1): kestrel-qp's solution of the condensed QP)
 *
 * Set-up, once: tiny_setup(A, B, f = 0, Q, R, rho), then the cache
 * recomputed with tiny_precompute_and_set_cache(A, B, f, diag Q, diag R):
 * tiny_setup of this version passes Q + rho I and R + rho I to it, which
 * adds rho again, so the QP the iteration converges to would weigh the
 * stages with Q + rho I and R + rho I; recomputed, they are Q and R and the
 * terminal weight Pinf - rho I (Pinf: the cache's Riccati solution for
 * Q + rho I, R + rho I), the QP the Rust side condenses. Settings: TinyMPC's
 * defaults (tiny_set_default_settings: abs_pri_tol = abs_dua_tol = 1e-3,
 * max_iter 1000, check every iteration, no adaptive rho), with state
 * bounds off (the problem has none) and, per config, both tolerances and
 * max_iter set as given.
 *
 * Every config runs on every set. A set labelled `cold` starts each solve
 * from TinyMPC's state after set-up (trajectories, slacks, duals and the
 * Riccati linear terms zeroed); any other set warm (the workspace of the
 * previous solve kept, as TinyMPC runs in a loop; not shifted in time).
 * Timed per solve with clock_gettime(CLOCK_MONOTONIC): copy x0 and the
 * input bounds into the workspace, (cold: reset), tiny_solve, copy the
 * inputs out. Output, one line per config and set:
 *   tinympc <name> <config>-<set> <count> <median_ns> <p99_ns> <max_ns>
 *        <mean_iter> <max_iter> <max_rel_dev_from_kestrel_qp> <unconverged>
 * The deviation covers every solve, converged or not.
 */
#include "tiny_api.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>

#include "../harness/bench_io.h"

static std::vector<double> read_vec(FILE *f, int len) {
    std::vector<double> v(len > 0 ? len : 0);
    bench_read_into(f, v.data(), len, "tinympc_bench");
    return v;
}

struct Config {
    char label[64];
    double tol;
    int max_iter;
};

/* TinyMPC's state right after set-up. */
static void reset(TinyWorkspace *w) {
    auto x0 = w->x.col(0).eval();
    for (tinyMatrix *m : {&w->x, &w->u, &w->q, &w->r, &w->p, &w->d, &w->v, &w->vnew, &w->z,
                          &w->znew, &w->g, &w->y})
        m->setZero();
    w->x.col(0) = x0;
}

int main(int argc, char **argv) {
    FILE *f = bench_open_input(argc, argv, "tinympc_bench", "<problem.txt>");
    char name[256];
    int nx, nu, N;
    double rho;
    while (fscanf(f, "%255s %d %d %d %lf", name, &nx, &nu, &N, &rho) == 5) {
        std::vector<double> a = read_vec(f, nx * nx), b = read_vec(f, nx * nu);
        std::vector<double> qd = read_vec(f, nx), rd = read_vec(f, nu);
        tinyMatrix A(nx, nx), B(nx, nu), Q = tinyMatrix::Zero(nx, nx),
                   R = tinyMatrix::Zero(nu, nu), fdyn = tinyMatrix::Zero(nx, 1);
        for (int i = 0; i < nx; i++) {
            for (int j = 0; j < nx; j++) A(i, j) = a[i * nx + j];
            for (int j = 0; j < nu; j++) B(i, j) = b[i * nu + j];
            Q(i, i) = qd[i];
        }
        for (int i = 0; i < nu; i++) R(i, i) = rd[i];
        int ncfg;
        if (fscanf(f, "%d", &ncfg) != 1 || ncfg <= 0) return 2;
        std::vector<Config> cfg(ncfg);
        for (auto &c : cfg)
            if (fscanf(f, "%63s %lf %d", c.label, &c.tol, &c.max_iter) != 3) return 2;
        int sets;
        if (fscanf(f, "%d", &sets) != 1) return 2;
        int nz = nu * (N - 1);
        for (int s = 0; s < sets; s++) {
            char label[64];
            int count;
            if (fscanf(f, "%63s %d", label, &count) != 2 || count <= 0) return 2;
            bool cold = strcmp(label, "cold") == 0;
            int per = nx + 3 * nz;
            std::vector<double> all = read_vec(f, count * per);
            for (const Config &c : cfg) {
                TinySolver *solver = nullptr;
                if (tiny_setup(&solver, A, B, fdyn, Q, R, rho, nx, nu, N, 0) != 0) {
                    fprintf(stderr, "tinympc_bench: setup failed\n");
                    return 1;
                }
                tiny_precompute_and_set_cache(solver->cache, A, B, fdyn, Q, R, nx, nu, rho, 0);
                tinyMatrix xmin = tinyMatrix::Constant(nx, N, -1e30),
                           xmax = tinyMatrix::Constant(nx, N, 1e30);
                tinyMatrix umin = tinyMatrix::Zero(nu, N - 1), umax = umin;
                tiny_set_bound_constraints(solver, xmin, xmax, umin, umax);
                TinySettings *st = solver->settings;
                st->en_state_bound = 0;
                st->abs_pri_tol = c.tol;
                st->abs_dua_tol = c.tol;
                st->max_iter = c.max_iter;
                TinyWorkspace *w = solver->work;
                std::vector<long> ns(count);
                std::vector<double> u(nz);
                long iter_sum = 0;
                int iter_max = 0, unconverged = 0;
                double worst = 0.0;
                for (int k = 0; k < count; k++) {
                    const double *smp = all.data() + (size_t)k * per;
                    const double *x0 = smp, *lo = smp + nx, *hi = smp + nx + nz;
                    const double *z = smp + nx + 2 * nz;
                    long t0 = bench_now_ns();
                    w->x.col(0) = Eigen::Map<const tinyVector>(x0, nx);
                    w->u_min = Eigen::Map<const tinyMatrix>(lo, nu, N - 1);
                    w->u_max = Eigen::Map<const tinyMatrix>(hi, nu, N - 1);
                    if (cold) reset(w);
                    int flag = tiny_solve(solver);
                    Eigen::Map<tinyMatrix>(u.data(), nu, N - 1) = solver->solution->u;
                    long t1 = bench_now_ns();
                    ns[k] = t1 - t0;
                    if (flag != 0) unconverged++;
                    iter_sum += solver->solution->iter;
                    iter_max = std::max(iter_max, solver->solution->iter);
                    double scale = 1.0, dev = 0.0;
                    for (int i = 0; i < nz; i++) scale = std::max(scale, std::fabs(z[i]) + 1.0);
                    for (int i = 0; i < nz; i++) dev = std::max(dev, std::fabs(u[i] - z[i]) / scale);
                    if (!std::isfinite(dev)) dev = INFINITY;
                    worst = std::max(worst, dev);
                }
                std::sort(ns.begin(), ns.end());
                printf("tinympc %s %s-%s %d %ld %ld %ld %.3f %d %.3e %d\n", name, c.label, label,
                       count, ns[count / 2], ns[(size_t)((count - 1) * 0.99)], ns[count - 1],
                       (double)iter_sum / count, iter_max, worst, unconverged);
                fflush(stdout);
            }
        }
    }
    fclose(f);
    return 0;
}
