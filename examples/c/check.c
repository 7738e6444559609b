/*
 * The C side of kestrel-tests' ffi_c test (tests/tests/ffi_c.rs): runs
 * kestrel-ffi through kestrel.h on the tables of kestrel_design.c and
 * prints every result as raw bits, so the Rust test can compare them with
 * the Rust library's bit for bit.
 *
 *     check loop-f32 | loop-q16      stdin: "fresh g0 g1 g2 r0 r1 r2 thr" (hex bits of f32)
 *                                    out:   "status pwm0 pwm1 pwm2 pwm3 flags iterations"
 *     check loop-empc-f32 | loop-empc-q16   the same with the explicit law
 *     check kalman-f32 | kalman-q16  stdin: "y0 y1 y2 u0 u1 u2 u3" (hex bits: f32 or Q15.16)
 *                                    out:   "status x0..x4 status x0..x4" (after the
 *                                           measurement update, after the time update)
 *     check fgm16-f32 | fgm16-q16    stdin: "theta0..theta8" (hex bits)
 *                                    out:   "status z0..z3 iterations"
 *     check fgm-f32 | fgm-q16        stdin: "theta0..theta8": the reference solve (cold start)
 *                                    out:   "status z0..z3"
 *     check empc-f32 | empc-q16      stdin: "x0..x4 r0..r3" (hex bits): the explicit law
 *                                    out:   "status u0..u3 nodes"
 *     check errors                   bad tables, NULL pointers, uninitialised states:
 *                                    one "ok <what>" or "FAIL <what> ..." line each;
 *                                    exit status = number of failures
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kestrel.h"
#include "kestrel_design.h"
#include "kestrel_empc.h"

static uint32_t f2u(float f) { uint32_t u; memcpy(&u, &f, 4); return u; }
static float u2f(uint32_t u) { float f; memcpy(&f, &u, 4); return f; }

/* Reads n hex words from a line; 0 at the end of the input. */
static int read_words(uint32_t *w, int n) {
    char line[512];
    if (!fgets(line, sizeof line, stdin)) return 0;
    char *p = line;
    for (int i = 0; i < n; i++) {
        char *end;
        w[i] = (uint32_t)strtoul(p, &end, 16);
        if (end == p) { fprintf(stderr, "bad input line: %s", line); exit(2); }
        p = end;
    }
    return 1;
}

static KestrelRateLoopF32 loop_f32;
static KestrelRateLoopQ16 loop_q16;
static KestrelRateLoopEmpcF32 loop_empc_f32;
static KestrelRateLoopEmpcQ16 loop_empc_q16;
static KestrelKalman16F32 kf_f32;
static KestrelKalman16Q16 kf_q16;
static KestrelFgm16F32 fgm_f32;
static KestrelFgm16Q16 fgm_q16;
static KestrelEmpc16F32 empc_f32;
static KestrelEmpc16Q16 empc_q16;

static int run_loop(int q16, int empc) {
    KestrelLoopConfig config;
    kestrel_loop_config_default(&config);
    KestrelDesign d = q16 ? kestrel_design_q16() : kestrel_design_f32();
    static KestrelEmpc16Tables t; /* outlives the loop */
    t = kestrel_empc_tables();
    KestrelStatus st = empc ? (q16 ? kestrel_rate_loop_init_empc_q16(&loop_empc_q16, &d, &t, &config)
                                   : kestrel_rate_loop_init_empc_f32(&loop_empc_f32, &d, &t, &config))
                            : (q16 ? kestrel_rate_loop_init_fgm_q16(&loop_q16, &d, &config)
                                   : kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config));
    if (st != KESTREL_STATUS_OK) { fprintf(stderr, "init: %d\n", (int)st); return 1; }
    uint32_t w[8];
    while (read_words(w, 8)) {
        KestrelRateInput in;
        memset(&in, 0, sizeof in);
        in.fresh = (uint8_t)w[0];
        for (int i = 0; i < 3; i++) {
            in.gyro[i] = u2f(w[1 + i]);
            in.reference[i] = u2f(w[4 + i]);
        }
        in.throttle = u2f(w[7]);
        KestrelRateOutput out;
        memset(&out, 0, sizeof out);
        st = empc ? (q16 ? kestrel_rate_loop_step_empc_q16(&loop_empc_q16, &in, NULL, &out)
                         : kestrel_rate_loop_step_empc_f32(&loop_empc_f32, &in, NULL, &out))
                  : (q16 ? kestrel_rate_loop_step_q16(&loop_q16, &in, NULL, &out)
                         : kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, &out));
        printf("%d %u %u %u %u %u %u\n", (int)st, out.pwm[0], out.pwm[1], out.pwm[2], out.pwm[3],
               out.flags, out.iterations);
    }
    return 0;
}

static int run_kalman(int q16) {
    KestrelDesign d = q16 ? kestrel_design_q16() : kestrel_design_f32();
    KestrelStatus st = q16 ? kestrel_kalman16_init_q16(&kf_q16, &d) : kestrel_kalman16_init_f32(&kf_f32, &d);
    if (st != KESTREL_STATUS_OK) { fprintf(stderr, "init: %d\n", (int)st); return 1; }
    uint32_t w[7];
    while (read_words(w, 7)) {
        uint32_t x[KESTREL_NX];
        for (int pass = 0; pass < 2; pass++) {
            memset(x, 0, sizeof x);
            if (q16) {
                st = pass == 0 ? kestrel_kalman16_measure_q16(&kf_q16, (const int32_t *)w, (int32_t *)x)
                               : kestrel_kalman16_predict_q16(&kf_q16, (const int32_t *)(w + 3), (int32_t *)x);
            } else {
                float v[7], xf[KESTREL_NX];
                for (int i = 0; i < 7; i++) v[i] = u2f(w[i]);
                memset(xf, 0, sizeof xf);
                st = pass == 0 ? kestrel_kalman16_measure_f32(&kf_f32, v, xf)
                               : kestrel_kalman16_predict_f32(&kf_f32, v + 3, xf);
                for (int i = 0; i < KESTREL_NX; i++) x[i] = f2u(xf[i]);
            }
            printf("%s%d", pass ? " " : "", (int)st);
            for (int i = 0; i < KESTREL_NX; i++) printf(" %08x", (unsigned)x[i]);
        }
        printf("\n");
    }
    return 0;
}

static int run_fgm(int q16, int reference) {
    KestrelDesign d = q16 ? kestrel_design_q16() : kestrel_design_f32();
    KestrelStatus st = KESTREL_STATUS_OK;
    if (!reference) {
        st = q16 ? kestrel_fgm16_init_q16(&fgm_q16, &d) : kestrel_fgm16_init_f32(&fgm_f32, &d);
        if (st != KESTREL_STATUS_OK) { fprintf(stderr, "init: %d\n", (int)st); return 1; }
    }
    uint32_t w[KESTREL_NP];
    while (read_words(w, KESTREL_NP)) {
        uint32_t z[KESTREL_NZ];
        uint16_t iterations = 0;
        memset(z, 0, sizeof z);
        if (q16) {
            st = reference ? kestrel_fgm_solve_q16(&d, (const int32_t *)w, NULL, (int32_t *)z)
                           : kestrel_fgm16_solve_q16(&fgm_q16, (const int32_t *)w, (int32_t *)z, &iterations);
        } else {
            float t[KESTREL_NP], zf[KESTREL_NZ];
            for (int i = 0; i < KESTREL_NP; i++) t[i] = u2f(w[i]);
            memset(zf, 0, sizeof zf);
            st = reference ? kestrel_fgm_solve_f32(&d, t, NULL, zf)
                           : kestrel_fgm16_solve_f32(&fgm_f32, t, zf, &iterations);
            for (int i = 0; i < KESTREL_NZ; i++) z[i] = f2u(zf[i]);
        }
        printf("%d", (int)st);
        for (int i = 0; i < KESTREL_NZ; i++) printf(" %08x", (unsigned)z[i]);
        if (!reference) printf(" %u", iterations);
        printf("\n");
    }
    return 0;
}

static int run_empc(int q16) {
    KestrelEmpc16Tables t = kestrel_empc_tables();
    KestrelStatus st = q16 ? kestrel_empc16_init_q16(&empc_q16, &t) : kestrel_empc16_init_f32(&empc_f32, &t);
    if (st != KESTREL_STATUS_OK) { fprintf(stderr, "init: %d\n", (int)st); return 1; }
    uint32_t w[KESTREL_NP];
    while (read_words(w, KESTREL_NP)) {
        uint32_t u[KESTREL_NU];
        uint16_t nodes = 0;
        memset(u, 0, sizeof u);
        if (q16) {
            st = kestrel_empc16_eval_q16(&empc_q16, (const int32_t *)w, (const int32_t *)(w + KESTREL_NX),
                                         (int32_t *)u, &nodes);
        } else {
            float p[KESTREL_NP], uf[KESTREL_NU];
            for (int i = 0; i < KESTREL_NP; i++) p[i] = u2f(w[i]);
            memset(uf, 0, sizeof uf);
            st = kestrel_empc16_eval_f32(&empc_f32, p, p + KESTREL_NX, uf, &nodes);
            for (int i = 0; i < KESTREL_NU; i++) u[i] = f2u(uf[i]);
        }
        printf("%d", (int)st);
        for (int i = 0; i < KESTREL_NU; i++) printf(" %08x", (unsigned)u[i]);
        printf(" %u\n", nodes);
    }
    return 0;
}

/* ---------------------------------------------------------------- errors */

static int failures = 0;

static void expect(const char *what, KestrelStatus got, KestrelStatus want) {
    if (got == want) {
        printf("ok %s\n", what);
    } else {
        printf("FAIL %s: status %d, expected %d\n", what, (int)got, (int)want);
        failures++;
    }
}

static void expect_true(const char *what, int cond) {
    if (cond) {
        printf("ok %s\n", what);
    } else {
        printf("FAIL %s\n", what);
        failures++;
    }
}

/* A copy of the f32 value table in RAM, to corrupt. */
static uint8_t values_copy[KESTREL_VALUES_BYTES];

static int run_errors(void) {
    KestrelLoopConfig config;
    KestrelDesign good = kestrel_design_f32(), d;
    KestrelRateInput in;
    KestrelRateOutput out;
    memset(&in, 0, sizeof in);
    memset(&out, 0, sizeof out);

    expect("abi version", kestrel_abi_version() == KESTREL_ABI_VERSION ? KESTREL_STATUS_OK : KESTREL_STATUS_BAD_SIZE, KESTREL_STATUS_OK);
    expect("config NULL", kestrel_loop_config_default(NULL), KESTREL_STATUS_NULL_POINTER);
    expect("config", kestrel_loop_config_default(&config), KESTREL_STATUS_OK);
    expect_true("config: the thesis's limits", config.esc_min == 1000 && config.esc_max == 2000 &&
                                                   config.servo_min == 1200 && config.servo_max == 1800);

    /* The checksum the export wrote is the library's CRC of the tables. */
    {
        KestrelBytes parts[3] = {good.values, good.kalman16, good.fgm16};
        uint16_t crc = 0;
        expect("checksum", kestrel_checksum(parts, 3, &crc), KESTREL_STATUS_OK);
        expect("checksum NULL out", kestrel_checksum(parts, 3, NULL), KESTREL_STATUS_NULL_POINTER);
        expect("checksum NULL tables", kestrel_checksum(NULL, 3, &crc), KESTREL_STATUS_NULL_POINTER);
    }

    /* NULL pointers. */
    expect("init NULL loop", kestrel_rate_loop_init_fgm_f32(NULL, &good, &config), KESTREL_STATUS_NULL_POINTER);
    expect("init NULL design", kestrel_rate_loop_init_fgm_f32(&loop_f32, NULL, &config), KESTREL_STATUS_NULL_POINTER);
    expect("init NULL config", kestrel_rate_loop_init_fgm_f32(&loop_f32, &good, NULL), KESTREL_STATUS_NULL_POINTER);
    {
        static KestrelEmpc16Tables et;
        et = kestrel_empc_tables();
        KestrelRateInput ein;
        KestrelRateOutput eout;
        memset(&ein, 0, sizeof ein);
        expect("empc loop init NULL tables", kestrel_rate_loop_init_empc_f32(&loop_empc_f32, &good, NULL, &config), KESTREL_STATUS_NULL_POINTER);
        expect("empc loop step after a failed init", kestrel_rate_loop_step_empc_f32(&loop_empc_f32, &ein, NULL, &eout), KESTREL_STATUS_NOT_INITIALISED);
        et.checksum ^= 1u;
        expect("empc loop tables checksum", kestrel_rate_loop_init_empc_f32(&loop_empc_f32, &good, &et, &config), KESTREL_STATUS_BAD_CHECKSUM);
        expect("f32 design to the q16 empc loop", kestrel_rate_loop_init_empc_q16(&loop_empc_q16, &good, &et, &config), KESTREL_STATUS_BAD_FORMAT);
    }
    d = good; d.values.data = NULL; d.values.flash = 0;
    expect("init NULL values table", kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config), KESTREL_STATUS_NULL_POINTER);
    d = good; d.kalman16.data = NULL; d.kalman16.flash = 0;
    expect("kalman init NULL rows", kestrel_kalman16_init_f32(&kf_f32, &d), KESTREL_STATUS_NULL_POINTER);
    d = good; d.fgm16.data = NULL; d.fgm16.flash = 0;
    expect("fgm16 init NULL rows", kestrel_fgm16_init_f32(&fgm_f32, &d), KESTREL_STATUS_NULL_POINTER);
    expect("kalman init NULL state", kestrel_kalman16_init_f32(NULL, &good), KESTREL_STATUS_NULL_POINTER);
    expect("fgm16 init NULL state", kestrel_fgm16_init_q16(NULL, &good), KESTREL_STATUS_NULL_POINTER);

    /* Uninitialised states (zeroed statics; a failed init). */
    expect("step uninitialised", kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, &out), KESTREL_STATUS_NOT_INITIALISED);
    {
        float y[3] = {0, 0, 0}, x[KESTREL_NX];
        expect("kalman measure uninitialised", kestrel_kalman16_measure_f32(&kf_f32, y, x), KESTREL_STATUS_NOT_INITIALISED);
    }

    /* Wrong sizes. */
    d = good; d.values.len -= 4;
    expect("values one value short", kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config), KESTREL_STATUS_BAD_SIZE);
    d = good; d.values.len += 4;
    expect("values one value long", kestrel_fgm16_init_f32(&fgm_f32, &d), KESTREL_STATUS_BAD_SIZE);
    d = good; d.kalman16.len -= 1;
    expect("kalman16 a byte short", kestrel_kalman16_init_f32(&kf_f32, &d), KESTREL_STATUS_BAD_SIZE);
    d = good; d.fgm16.len = 0;
    expect("fgm16 empty", kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config), KESTREL_STATUS_BAD_SIZE);

    /* Wrong checksum: the field, a table byte, the iteration count. */
    d = good; d.checksum ^= 1;
    expect("checksum field off by one bit", kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config), KESTREL_STATUS_BAD_CHECKSUM);
    d = kestrel_design_q16(); d.checksum = good.checksum;
    expect("q16 tables with the f32 checksum", kestrel_rate_loop_init_fgm_q16(&loop_q16, &d, &config), KESTREL_STATUS_BAD_CHECKSUM);
#if !defined(__AVR__)
    memcpy(values_copy, good.values.data, sizeof values_copy);
    values_copy[17] ^= 0x01;
    d = good; d.values.data = values_copy;
    expect("a flipped bit in the values", kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config), KESTREL_STATUS_BAD_CHECKSUM);
#endif
    d = good; d.fgm_iterations += 1;
    expect("another iteration count", kestrel_fgm16_init_f32(&fgm_f32, &d), KESTREL_STATUS_BAD_CHECKSUM);

    /* Wrong format: f32 tables to the Q15.16 loop and the other way round. */
    expect("f32 tables to the q16 loop", kestrel_rate_loop_init_fgm_q16(&loop_q16, &good, &config), KESTREL_STATUS_BAD_FORMAT);
    d = kestrel_design_q16();
    expect("q16 tables to the f32 fgm", kestrel_fgm16_init_f32(&fgm_f32, &d), KESTREL_STATUS_BAD_FORMAT);
    d = good; d.values_format = 7;
    expect("unknown value format", kestrel_rate_loop_init_fgm_f32(&loop_f32, &d, &config), KESTREL_STATUS_BAD_FORMAT);

    /* A failed init leaves the state unusable. */
    expect("step after a failed init", kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, &out), KESTREL_STATUS_NOT_INITIALISED);

    /* Crossed limits. */
    {
        KestrelLoopConfig bad = config;
        bad.esc_min = 2100;
        expect("crossed ESC limits", kestrel_rate_loop_init_fgm_f32(&loop_f32, &good, &bad), KESTREL_STATUS_INVALID_TABLE);
    }

    /* The good tables work; NULL input/output at the step. */
    expect("init", kestrel_rate_loop_init_fgm_f32(&loop_f32, &good, &config), KESTREL_STATUS_OK);
    expect("step NULL input", kestrel_rate_loop_step_f32(&loop_f32, NULL, NULL, &out), KESTREL_STATUS_NULL_POINTER);
    expect("step NULL output", kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, NULL), KESTREL_STATUS_NULL_POINTER);
    expect("step NULL loop", kestrel_rate_loop_step_f32(NULL, &in, NULL, &out), KESTREL_STATUS_NULL_POINTER);
    in.fresh = 1;
    in.throttle = 1500.0f;
    expect("step", kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, &out), KESTREL_STATUS_OK);
    expect_true("step: no flags", out.flags == 0);
    /* A non-finite input is no error code: the failsafe's pulses, flagged. */
    in.gyro[1] = NAN;
    expect("step NaN gyro", kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, &out), KESTREL_STATUS_OK);
    expect_true("NaN gyro: failsafe pulses and flags",
                (out.flags & KESTREL_FLAG_FAILSAFE) && (out.flags & KESTREL_FLAG_NON_FINITE) &&
                    out.pwm[0] == config.safe_esc && out.pwm[1] == config.safe_esc &&
                    out.pwm[2] == config.safe_esc && out.pwm[3] == config.safe_servo);
    {
        float theta[KESTREL_NP], z[KESTREL_NZ];
        memset(theta, 0, sizeof theta);
        theta[3] = INFINITY;
        expect("fgm16 init", kestrel_fgm16_init_f32(&fgm_f32, &good), KESTREL_STATUS_OK);
        expect("fgm16 infinite theta", kestrel_fgm16_solve_f32(&fgm_f32, theta, z, NULL), KESTREL_STATUS_NON_FINITE);
        expect("fgm16 NULL theta", kestrel_fgm16_solve_f32(&fgm_f32, NULL, z, NULL), KESTREL_STATUS_NULL_POINTER);
    }
    /* The explicit law's tables. */
    {
        KestrelEmpc16Tables t = kestrel_empc_tables(), b;
        expect("empc init", kestrel_empc16_init_f32(&empc_f32, &t), KESTREL_STATUS_OK);
        expect("empc init NULL state", kestrel_empc16_init_f32(NULL, &t), KESTREL_STATUS_NULL_POINTER);
        expect("empc init NULL tables", kestrel_empc16_init_f32(&empc_f32, NULL), KESTREL_STATUS_NULL_POINTER);
        b = t; b.chunks = NULL;
        expect("empc NULL chunks", kestrel_empc16_init_f32(&empc_f32, &b), KESTREL_STATUS_NULL_POINTER);
        b = t; b.n_chunks = 0;
        expect("empc no chunks", kestrel_empc16_init_f32(&empc_f32, &b), KESTREL_STATUS_BAD_SIZE);
        b = t; b.checksum ^= 0x0100u;
        expect("empc checksum", kestrel_empc16_init_q16(&empc_q16, &b), KESTREL_STATUS_BAD_CHECKSUM);
        b = t; b.layout.n_nodes += 1;
        expect("empc layout off by one node", kestrel_empc16_init_f32(&empc_f32, &b), KESTREL_STATUS_BAD_CHECKSUM);
        {
            float x[KESTREL_NX], r[KESTREL_NR], u[KESTREL_NU];
            memset(x, 0, sizeof x);
            memset(r, 0, sizeof r);
            expect("empc eval after a failed init", kestrel_empc16_eval_f32(&empc_f32, x, r, u, NULL),
                   KESTREL_STATUS_NOT_INITIALISED);
        }
    }
    printf("%d failure(s)\n", failures);
    return failures;
}

int main(int argc, char **argv) {
    const char *m = argc > 1 ? argv[1] : "";
    if (!strcmp(m, "loop-f32")) return run_loop(0, 0);
    if (!strcmp(m, "loop-q16")) return run_loop(1, 0);
    if (!strcmp(m, "loop-empc-f32")) return run_loop(0, 1);
    if (!strcmp(m, "loop-empc-q16")) return run_loop(1, 1);
    if (!strcmp(m, "kalman-f32")) return run_kalman(0);
    if (!strcmp(m, "kalman-q16")) return run_kalman(1);
    if (!strcmp(m, "fgm16-f32")) return run_fgm(0, 0);
    if (!strcmp(m, "fgm16-q16")) return run_fgm(1, 0);
    if (!strcmp(m, "fgm-f32")) return run_fgm(0, 1);
    if (!strcmp(m, "fgm-q16")) return run_fgm(1, 1);
    if (!strcmp(m, "empc-f32")) return run_empc(0);
    if (!strcmp(m, "empc-q16")) return run_empc(1);
    if (!strcmp(m, "errors")) return run_errors();
    fprintf(stderr, "usage: check loop-f32|loop-q16|loop-empc-f32|loop-empc-q16|kalman-f32|kalman-q16|fgm16-f32|fgm16-q16|fgm-f32|fgm-q16|empc-f32|empc-q16|errors\n");
    return 2;
}
