/*
 * Times qpOASES (dense, online active set) on the problems written by
 * kestrel-benches' example `qp_compare` (see scripts/qp-bench.sh): the same
 * input file as benches/daqp/daqp_bench.c. No Python anywhere: qpOASES's
 * C++ sources (the `cmeel-qpoases` sdist's qpOASES/, version pinned in the
 * script) are compiled together with this file.
 *
 * Input (text, whitespace separated; `inf`/`-inf` allowed):
 *   name n m sets
 *   H (n*n, row-major) G (m*n, row-major)
 *   per set: label count, then per sample:
 *     q (n) l (m) u (m) lb (n) ub (n) z (n: kestrel-qp's solution) iterations
 *
 * The QP class: QProblemB when m = 0 (bounds only: every problem of the
 * comparison), QProblem otherwise. Two option sets, each run on every set:
 * `mpc` (Options::setToMPC()) and `default` (Options::setToDefault()), both
 * with printLevel = PL_NONE. Per set labelled `cold`, two timings:
 *   <opts>-cold: hotstart from the empty working set: before each timed
 *     solve (untimed) the object is re-initialised at the unconstrained QP
 *     (g = 0, no finite bounds: x = 0, every bound inactive), so the timed
 *     hotstart walks the homotopy from there, H's factor kept (as DAQP's
 *     cold start keeps its factor of H);
 *   <opts>-init: init() from scratch on a constructed object (H copied
 *     and factorised, the homotopy from qpOASES's own trivial start).
 * Per any other set, <opts>-warm: one object hotstarted from the previous
 * sample's solution (qpOASES's own warm start: the homotopy from the last
 * working set and factor).
 * Timed per solve with clock_gettime(CLOCK_MONOTONIC), including the
 * getPrimalSolution copy. Output, one line per timing:
 *   qpoases <name> <label> <count> <median_ns> <p99_ns> <max_ns> <mean_iter>
 *        <max_iter> <max_rel_dev_from_kestrel_qp> <failures>
 * Iterations: qpOASES's nWSR on return (working-set changes).
 */
#include <qpOASES.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <vector>

#include "../harness/bench_io.h"

USING_NAMESPACE_QPOASES

static std::vector<double> read_vec(FILE *f, int len) {
    std::vector<double> v(len > 0 ? len : 0);
    bench_read_into(f, v.data(), len, "qpoases_bench");
    return v;
}

static double clamp_inf(double v) {
    if (v >= INFTY) return INFTY;
    if (v <= -INFTY) return -INFTY;
    return v;
}

struct Sample {
    std::vector<double> q, lb, ub, lba, uba, z;
};

/* One timing's accumulators. */
struct Acc {
    std::vector<long> ns;
    long iter_sum = 0;
    int iter_max = 0, failures = 0;
    double worst = 0.0;
    void add(long t, bool ok, int iter, const double *x, const double *z, int n) {
        ns.push_back(t);
        if (!ok) {
            failures++;
            return;
        }
        iter_sum += iter;
        if (iter > iter_max) iter_max = iter;
        double scale = 1.0, dev = 0.0;
        for (int i = 0; i < n; i++)
            if (std::fabs(z[i]) + 1.0 > scale) scale = std::fabs(z[i]) + 1.0;
        for (int i = 0; i < n; i++) dev = std::max(dev, std::fabs(x[i] - z[i]) / scale);
        if (!std::isfinite(dev)) dev = INFINITY;
        worst = std::max(worst, dev);
    }
    void print(const char *name, const char *label) {
        std::sort(ns.begin(), ns.end());
        size_t count = ns.size();
        int solved = (int)count - failures;
        printf("qpoases %s %s %zu %ld %ld %ld %.3f %d %.3e %d\n", name, label, count,
               ns[count / 2], ns[(size_t)((count - 1) * 0.99)], ns[count - 1],
               (double)iter_sum / (solved > 0 ? solved : 1), iter_max, worst, failures);
        fflush(stdout);
    }
};

/* The problem's fixed data and one solver object of either class. */
struct Solver {
    int n, m;
    const double *h, *g;
    Options opts;
    QProblemB *b = nullptr;
    QProblem *c = nullptr;
    Solver(int n_, int m_, const double *h_, const double *g_, const Options &o)
        : n(n_), m(m_), h(h_), g(g_), opts(o) {
        fresh();
    }
    ~Solver() {
        delete b;
        delete c;
    }
    void fresh() {
        delete b;
        delete c;
        b = nullptr;
        c = nullptr;
        if (m == 0) {
            b = new QProblemB(n);
            b->setOptions(opts);
        } else {
            c = new QProblem(n, m);
            c->setOptions(opts);
        }
    }
    returnValue init(const Sample &s, int_t &nwsr) {
        if (b) return b->init(h, s.q.data(), s.lb.data(), s.ub.data(), nwsr);
        return c->init(h, s.q.data(), g, s.lb.data(), s.ub.data(), s.lba.data(), s.uba.data(),
                       nwsr);
    }
    returnValue hotstart(const Sample &s, int_t &nwsr) {
        if (b) return b->hotstart(s.q.data(), s.lb.data(), s.ub.data(), nwsr);
        return c->hotstart(s.q.data(), s.lb.data(), s.ub.data(), s.lba.data(), s.uba.data(),
                           nwsr);
    }
    void solution(double *x) {
        if (b)
            b->getPrimalSolution(x);
        else
            c->getPrimalSolution(x);
    }
};

static const int_t NWSR_CAP = 10000;

int main(int argc, char **argv) {
    FILE *f = bench_open_input(argc, argv, "qpoases_bench", "<problems.txt>");
    char name[256];
    int n, m, sets;
    while (fscanf(f, "%255s %d %d %d", name, &n, &m, &sets) == 4) {
        std::vector<double> h = read_vec(f, n * n);
        std::vector<double> g = read_vec(f, m * n);
        std::vector<double> x(n);
        /* The unconstrained QP at g = 0: x = 0, every bound inactive. */
        Sample origin;
        origin.q.assign(n, 0.0);
        origin.lb.assign(n, -INFTY);
        origin.ub.assign(n, INFTY);
        origin.lba.assign(m, -INFTY);
        origin.uba.assign(m, INFTY);
        for (int s = 0; s < sets; s++) {
            char label[64];
            int count;
            if (fscanf(f, "%63s %d", label, &count) != 2 || count <= 0) {
                fprintf(stderr, "qpoases_bench: malformed set header\n");
                return 2;
            }
            bool cold = strcmp(label, "cold") == 0;
            std::vector<Sample> smp(count);
            for (int k = 0; k < count; k++) {
                Sample &p = smp[k];
                p.q = read_vec(f, n);
                p.lba = read_vec(f, m);
                p.uba = read_vec(f, m);
                p.lb = read_vec(f, n);
                p.ub = read_vec(f, n);
                p.z = read_vec(f, n);
                read_vec(f, 1); /* kestrel-qp's iterations */
                for (auto *v : {&p.lba, &p.uba, &p.lb, &p.ub})
                    for (double &e : *v) e = clamp_inf(e);
            }
            for (int mode = 0; mode < 2; mode++) {
                Options o;
                if (mode == 0)
                    o.setToMPC();
                else
                    o.setToDefault();
                o.printLevel = PL_NONE;
                const char *tag = mode == 0 ? "mpc" : "default";
                char lab[96];
                Solver sv(n, m, h.data(), g.data(), o);
                if (cold) {
                    Acc hot, init;
                    for (int k = 0; k < count; k++) {
                        int_t nwsr = NWSR_CAP;
                        sv.init(origin, nwsr); /* untimed: the empty working set */
                        nwsr = NWSR_CAP;
                        long t0 = bench_now_ns();
                        returnValue r = sv.hotstart(smp[k], nwsr);
                        sv.solution(x.data());
                        long t1 = bench_now_ns();
                        hot.add(t1 - t0, r == SUCCESSFUL_RETURN, (int)nwsr, x.data(),
                                smp[k].z.data(), n);
                    }
                    snprintf(lab, sizeof lab, "%s-cold", tag);
                    hot.print(name, lab);
                    for (int k = 0; k < count; k++) {
                        sv.fresh(); /* untimed: a constructed, uninitialised object */
                        int_t nwsr = NWSR_CAP;
                        long t0 = bench_now_ns();
                        returnValue r = sv.init(smp[k], nwsr);
                        sv.solution(x.data());
                        long t1 = bench_now_ns();
                        init.add(t1 - t0, r == SUCCESSFUL_RETURN, (int)nwsr, x.data(),
                                 smp[k].z.data(), n);
                    }
                    snprintf(lab, sizeof lab, "%s-init", tag);
                    init.print(name, lab);
                } else {
                    Acc warm;
                    int_t nwsr = NWSR_CAP;
                    sv.init(origin, nwsr); /* the walk starts from the empty set */
                    for (int k = 0; k < count; k++) {
                        nwsr = NWSR_CAP;
                        long t0 = bench_now_ns();
                        returnValue r = sv.hotstart(smp[k], nwsr);
                        sv.solution(x.data());
                        long t1 = bench_now_ns();
                        warm.add(t1 - t0, r == SUCCESSFUL_RETURN, (int)nwsr, x.data(),
                                 smp[k].z.data(), n);
                        if (r != SUCCESSFUL_RETURN) {
                            /* A failed hotstart leaves the object unusable:
                               start the next one from the empty set. */
                            sv.fresh();
                            int_t w = NWSR_CAP;
                            sv.init(origin, w);
                        }
                    }
                    snprintf(lab, sizeof lab, "%s-%s", tag, label);
                    warm.print(name, lab);
                }
            }
        }
    }
    fclose(f);
    return 0;
}
