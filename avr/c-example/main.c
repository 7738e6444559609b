/*
 * The kestrel rate loop in C on the ATmega2560 (avr-gcc), through
 * kestrel-ffi's C ABI (kestrel.h, the avr-none staticlib) and the tables of
 * `kestrel export --lang c` (kestrel_design.c, in flash). Runs in simavr:
 *
 *     simavr -m atmega2560 -f 16000000 kestrel-c-example-f32.elf
 *
 * The period is composed from kestrel-ffi's pieces, as kestrel-avr-rt's
 * RateLoop composes it (and examples/c/rate_loop.c gets it in one call):
 * gyro minus bias, the 16-bit Kalman filter's measurement update, the fast
 * gradient law on theta = [x; reference; throttle], the time update with
 * the moves, the mixer (the design's offsets plus the moves, the throttle
 * into the ESCs), rounding and the PWM limits; a missing sample holds the
 * last pulses once, then the failsafe's; a non-finite one gives the
 * failsafe's at once; the first good sample after it restarts the filter.
 * (The one-call kestrel_rate_loop_init_fgm_f32 needs more stack than the
 * chip's 8 kB of RAM today; see avr/c-example/README.md.)
 *
 * A fixed sequence of PERIODS gyro samples (a first-order rate response
 * towards the reference with pseudo-random noise, in integer arithmetic so
 * the host repeats it exactly; the reference steps at STEP_AT; missing
 * samples at 150, 200, 201 and a NaN at 250) prints one line per period
 * on USART0:
 *
 *     P k status pwm1 pwm2 pwm3 servo flags iterations kalman_cycles solver_cycles step_cycles
 *
 * the cycles counted by Timer1 at the CPU clock (the counter the Rust
 * firmware uses, kestrel_avr_rt::cycles::timer1), then the error codes of
 * bad tables read from flash ("E ok ..."), and "END". Built with
 * -DKESTREL_EXAMPLE_Q16 (make SCALAR=q16) it runs the Q15.16 functions on
 * the Q15.16 tables; with -DKESTREL_EXAMPLE_EMPC (make LAW=empc) the
 * explicit law of `kestrel export --lang c --empc` (kestrel_empc.c, in
 * flash) instead of the fast gradient. tests/tests/ffi_c.rs
 * builds it (Makefile here), runs it and checks every line against the
 * Rust library's rate loop.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "kestrel.h"
#include "kestrel_design.h"

#define PERIODS 300
#define STEP_AT 100

/* ---- the cycle counter: Timer1 at clk/1, its overflows counted in software */

static volatile uint16_t timer1_overflows;

ISR(TIMER1_OVF_vect) { timer1_overflows++; }

static void timer1_start(void) {
    TCCR1A = 0;
    TCCR1B = 0;
    TCNT1 = 0;
    TIFR1 = _BV(TOV1);
    TIMSK1 = _BV(TOIE1);
    TCCR1B = _BV(CS10);
}

/* The 32-bit count: a pending overflow (the counter wrapped, its interrupt
 * has not run yet) belongs to a small counter value. */
static uint32_t timer1_now(void *ctx) {
    (void)ctx;
    uint8_t sreg = SREG;
    cli();
    uint16_t lo = TCNT1;
    uint8_t pending = TIFR1 & _BV(TOV1);
    uint16_t hi = timer1_overflows;
    SREG = sreg;
    if (pending && lo < 0x8000u) hi++;
    return ((uint32_t)hi << 16) | lo;
}

/* ---- USART0 at 250000 baud (UBRR 3 at 16 MHz), transmit by polling */

static void uart_init(void) {
    UBRR0H = 0;
    UBRR0L = 3;
    UCSR0A = 0;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    UCSR0B = _BV(TXEN0);
}

static void put(char c) {
    while (!(UCSR0A & _BV(UDRE0))) {}
    UDR0 = c;
}

static void put_str(const char *s) {
    while (*s) put(*s++);
}

static void put_u32(uint32_t v) {
    char b[11];
    uint8_t i = sizeof b;
    b[--i] = 0;
    do {
        b[--i] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    put(' ');
    put_str(b + i);
}

/* ---- the input sequence (the Rust test repeats it) */

static uint32_t seed = 0x2545F491u;

static uint32_t xorshift32(void) {
    seed ^= seed << 13;
    seed ^= seed >> 17;
    seed ^= seed << 5;
    return seed;
}

#ifdef KESTREL_EXAMPLE_EMPC
/* The explicit law (kestrel export --lang c --empc) instead of the fast gradient. */
#include "kestrel_empc.h"
#ifdef KESTREL_EXAMPLE_Q16
static KestrelEmpc16Q16 law;
#define LAW_INIT(l, d) kestrel_empc16_init_q16((l), &empc_tables)
#define LAW_SOLVE(l, theta, u, n) kestrel_empc16_eval_q16((l), (theta), (theta) + KESTREL_NX, (u), (n))
#else
static KestrelEmpc16F32 law;
#define LAW_INIT(l, d) kestrel_empc16_init_f32((l), &empc_tables)
#define LAW_SOLVE(l, theta, u, n) kestrel_empc16_eval_f32((l), (theta), (theta) + KESTREL_NX, (u), (n))
#endif
/* The chunk descriptors stay in RAM while the law is used. */
static KestrelEmpc16Tables empc_tables;
#else
#ifdef KESTREL_EXAMPLE_Q16
static KestrelFgm16Q16 law;
#define LAW_INIT(l, d) kestrel_fgm16_init_q16((l), (d))
#define LAW_SOLVE(l, theta, u, n) kestrel_fgm16_solve_q16((l), (theta), (u), (n))
#else
static KestrelFgm16F32 law;
#define LAW_INIT(l, d) kestrel_fgm16_init_f32((l), (d))
#define LAW_SOLVE(l, theta, u, n) kestrel_fgm16_solve_f32((l), (theta), (u), (n))
#endif
#endif

#ifdef KESTREL_EXAMPLE_Q16
/* The Q15.16 loop: values are int32_t raw bits (value = bits / 65536). */
typedef int32_t S;
static KestrelKalman16Q16 filter;
#define DESIGN kestrel_design_q16
#define KALMAN_INIT kestrel_kalman16_init_q16
#define KALMAN_RESET kestrel_kalman16_reset_q16
#define KALMAN_MEASURE kestrel_kalman16_measure_q16
#define KALMAN_PREDICT kestrel_kalman16_predict_q16
/* As kestrel-avr-rt's from_f32_fast: scaled by 2^16 (exact), truncated. */
static S from_f32(float v) { return (int32_t)(v * 65536.0f); }
static S value(uint8_t i) { return (int32_t)pgm_read_dword(&kestrel_design_values_q16[i]); }
/* Rounds to whole microseconds (half up, as kestrel-avr-rt's Q15.16
 * to_us) and clamps to [lo, hi]. */
static uint16_t pulse(S v, uint16_t lo, uint16_t hi) {
    int32_t us = (int32_t)(((int64_t)v + 32768) >> 16);
    return us < lo ? lo : us > hi ? hi : (uint16_t)us;
}
#else
typedef float S;
static KestrelKalman16F32 filter;
#define DESIGN kestrel_design_f32
#define KALMAN_INIT kestrel_kalman16_init_f32
#define KALMAN_RESET kestrel_kalman16_reset_f32
#define KALMAN_MEASURE kestrel_kalman16_measure_f32
#define KALMAN_PREDICT kestrel_kalman16_predict_f32
static S from_f32(float v) { return v; }
static S value(uint8_t i) { return pgm_read_float(&kestrel_design_values_f32[i]); }
/* Rounds to whole microseconds as kestrel-avr-rt does (half away from zero)
 * and clamps to [lo, hi]. */
static uint16_t pulse(S v, uint16_t lo, uint16_t hi) {
    int32_t us = v >= 0.0f ? (int32_t)(v + 0.5f) : (int32_t)(v - 0.5f);
    return us < lo ? lo : us > hi ? hi : (uint16_t)us;
}
#endif

static void expect(const char *what, KestrelStatus got, KestrelStatus want) {
    put_str(got == want ? "E ok " : "E FAIL ");
    put_str(what);
    put_u32((uint32_t)got);
    put('\n');
}


int main(void) {
    uart_init();
    timer1_start();
    sei();

    KestrelLoopConfig config; /* the limits and failsafe pulses */
    kestrel_loop_config_default(&config);
    KestrelDesign design = DESIGN();
    KestrelStatus st = KALMAN_INIT(&filter, &design);
#ifdef KESTREL_EXAMPLE_EMPC
    empc_tables = kestrel_empc_tables();
#endif
    KestrelStatus st2 = LAW_INIT(&law, &design);
    put_str("INIT");
    put_u32((uint32_t)st | (uint32_t)st2);
    put_u32(design.values.flash);
    put('\n');
    S bias[3], offset[4];
    for (uint8_t i = 0; i < 3; i++) bias[i] = value(KESTREL_DESIGN_OFF_BIAS + i);
    for (uint8_t i = 0; i < 4; i++) offset[i] = value(KESTREL_DESIGN_OFF_MIX_OFFSET + i);

    uint16_t pwm[4] = {config.safe_esc, config.safe_esc, config.safe_esc, config.safe_servo};
    uint8_t missing = 0, failsafe = 1; /* the failsafe's pulses until the first sample */
    /* Rates and references in 1/1024 rad/s (exact in f32). */
    int32_t rate[3] = {2048, 2048, 2048};
    static const int16_t step[3] = {1024, -1024, 512};
    for (uint16_t k = 0; k < PERIODS; k++) {
        int32_t ref[3];
        float gyro[3];
        S theta[KESTREL_NP];
        for (uint8_t i = 0; i < 3; i++) {
            ref[i] = k < STEP_AT ? 0 : step[i];
            int32_t noise = (int32_t)(xorshift32() >> 26) - 32; /* +-32/1024 rad/s */
            gyro[i] = (float)(rate[i] + noise) * (1.0f / 1024.0f);
            theta[KESTREL_NX + i] = from_f32((float)ref[i] * (1.0f / 1024.0f));
            rate[i] += (ref[i] - rate[i]) / 8;
        }
        S throttle = from_f32(1500.0f);
        theta[KESTREL_NX + 3] = throttle;
        uint8_t fresh = !(k == 150 || k == 200 || k == 201);
        if (k == 250) gyro[1] = NAN;

        uint8_t flags = 0;
        uint16_t iterations = 0;
        uint32_t t0 = timer1_now(NULL), t1 = t0, t2 = t0, t3 = t0;
        st = KESTREL_STATUS_OK;
        if (!fresh) {
            if (++missing == 1 && !failsafe) {
                flags = KESTREL_FLAG_HOLD; /* the last pulses, once */
            } else {
                failsafe = 1;
                flags = KESTREL_FLAG_FAILSAFE | KESTREL_FLAG_TIMEOUT;
            }
        } else if (!isfinite(gyro[0]) || !isfinite(gyro[1]) || !isfinite(gyro[2])) {
            failsafe = 1;
            flags = KESTREL_FLAG_FAILSAFE | KESTREL_FLAG_NON_FINITE;
        } else {
            missing = 0;
            if (failsafe) {
                /* Recovery: restart the estimator at the operating point. */
                static const S x0[KESTREL_NX];
                st = KALMAN_RESET(&filter, x0);
                failsafe = 0;
            }
            S y[3], u[KESTREL_NZ];
            for (uint8_t i = 0; i < 3; i++) y[i] = from_f32(gyro[i]) - bias[i];
            t0 = timer1_now(NULL);
            st |= KALMAN_MEASURE(&filter, y, theta); /* x into theta[0..NX] */
            t1 = timer1_now(NULL);
            st |= LAW_SOLVE(&law, theta, u, &iterations);
            t2 = timer1_now(NULL);
            st |= KALMAN_PREDICT(&filter, u, NULL);
            t3 = timer1_now(NULL);
            for (uint8_t i = 0; i < 4; i++) {
                S v = offset[i] + u[i];
                if (i < 3) v = v + throttle;
                pwm[i] = i < 3 ? pulse(v, config.esc_min, config.esc_max)
                               : pulse(v, config.servo_min, config.servo_max);
            }
        }
        if (failsafe) {
            pwm[0] = pwm[1] = pwm[2] = config.safe_esc;
            pwm[3] = config.safe_servo;
        }
        uint32_t t4 = timer1_now(NULL);
        put('P');
        put_u32(k);
        put_u32((uint32_t)st);
        for (uint8_t i = 0; i < 4; i++) put_u32(pwm[i]);
        put_u32(flags);
        put_u32(iterations);
        put_u32((t1 - t0) + (t3 - t2));
        put_u32(t2 - t1);
        put_u32(t4 - t0);
        put('\n');
    }

    /* Bad tables, read from flash. */
    KestrelDesign d = design;
    d.values.flash = 0;
    expect("no table address", KALMAN_INIT(&filter, &d), KESTREL_STATUS_NULL_POINTER);
    d = design;
    d.kalman16.len -= 2;
    expect("kalman16 short", KALMAN_INIT(&filter, &d), KESTREL_STATUS_BAD_SIZE);
    d = design;
    d.checksum ^= 0x8000u;
    expect("checksum", KALMAN_INIT(&filter, &d), KESTREL_STATUS_BAD_CHECKSUM);
    d = design;
    d.values.flash += 4; /* the table one value further on: its bytes differ */
    expect("moved table", KALMAN_INIT(&filter, &d), KESTREL_STATUS_BAD_CHECKSUM);
    S y[3] = {0, 0, 0};
    expect("measure after a failed init", KALMAN_MEASURE(&filter, y, NULL), KESTREL_STATUS_NOT_INITIALISED);
    put_str("END\n");
    /* Ends the simulation (simavr: sleeping with interrupts off). */
    cli();
    sleep_cpu();
    for (;;) {}
}
