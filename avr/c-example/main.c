/*
 * The kestrel rate loop in C on the ATmega2560 (avr-gcc), through
 * kestrel-ffi's C ABI (kestrel.h, the avr-none staticlib) and the tables of
 * `kestrel export --lang c` (kestrel_design.c, in flash). Runs in simavr:
 *
 *     simavr -m atmega2560 -f 16000000 kestrel-c-example-f32.elf
 *
 * One call per period (kestrel_rate_loop_step_f32 and friends, the loop
 * state a static built in place by kestrel_rate_loop_init_fgm_f32 /
 * _empc_f32): gyro sample, reference and throttle in, the four pulses, the
 * flags and the stage cycles (through a KestrelClock on Timer1) out; the
 * loop is kestrel-avr-rt's RateLoop as the Rust firmware builds it.
 * The stack is painted at start-up and its peak read back at the end
 * ("STACK bytes": RAMEND down to the deepest byte written).
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
 * bad tables read from flash ("E ok ..."), the peak stack ("STACK n") and
 * "END". Built with
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
/* The chunk descriptors stay in RAM while the loop is used. */
static KestrelEmpc16Tables empc_tables;
#ifdef KESTREL_EXAMPLE_Q16
static KestrelRateLoopEmpcQ16 rate_loop;
#define LOOP_INIT(l, d, c) kestrel_rate_loop_init_empc_q16((l), (d), &empc_tables, (c))
#define LOOP_STEP kestrel_rate_loop_step_empc_q16
#else
static KestrelRateLoopEmpcF32 rate_loop;
#define LOOP_INIT(l, d, c) kestrel_rate_loop_init_empc_f32((l), (d), &empc_tables, (c))
#define LOOP_STEP kestrel_rate_loop_step_empc_f32
#endif
#else
#ifdef KESTREL_EXAMPLE_Q16
static KestrelRateLoopQ16 rate_loop;
#define LOOP_INIT(l, d, c) kestrel_rate_loop_init_fgm_q16((l), (d), (c))
#define LOOP_STEP kestrel_rate_loop_step_q16
#else
static KestrelRateLoopF32 rate_loop;
#define LOOP_INIT(l, d, c) kestrel_rate_loop_init_fgm_f32((l), (d), (c))
#define LOOP_STEP kestrel_rate_loop_step_f32
#endif
#endif

#ifdef KESTREL_EXAMPLE_Q16
#define DESIGN kestrel_design_q16 /* the Q15.16 tables */
#else
#define DESIGN kestrel_design_f32
#endif

/* ---- the peak stack: RAM between the end of .bss and the stack pointer
 * painted at start-up, the first byte still painted found at the end */

extern uint8_t _end; /* avr-libc's linker script: the end of .bss/.noinit */
#define PAINT 0xA5

static uint16_t stack_peak(void) {
    const uint8_t *p = &_end;
    while (p <= (const uint8_t *)RAMEND && *p == PAINT) p++;
    return (uint16_t)((const uint8_t *)RAMEND - p + 1);
}

static void expect(const char *what, KestrelStatus got, KestrelStatus want) {
    put_str(got == want ? "E ok " : "E FAIL ");
    put_str(what);
    put_u32((uint32_t)got);
    put('\n');
}


int main(void) {
    /* Paint the free RAM below main's frame (the pointer in registers). */
    for (uint8_t *p = &_end; p < (uint8_t *)SP - 8; p++) *p = PAINT;
    uart_init();
    timer1_start();
    sei();

    KestrelLoopConfig config; /* the limits and failsafe pulses */
    kestrel_loop_config_default(&config);
    KestrelDesign design = DESIGN();
#ifdef KESTREL_EXAMPLE_EMPC
    empc_tables = kestrel_empc_tables();
#endif
    KestrelStatus st = LOOP_INIT(&rate_loop, &design, &config);
    put_str("INIT");
    put_u32((uint32_t)st);
    put_u32(design.values.flash);
    put('\n');

    const KestrelClock clock = {timer1_now, NULL};
    /* Rates and references in 1/1024 rad/s (exact in f32). */
    int32_t rate[3] = {2048, 2048, 2048};
    static const int16_t step[3] = {1024, -1024, 512};
    for (uint16_t k = 0; k < PERIODS; k++) {
        KestrelRateInput in;
        for (uint8_t i = 0; i < 3; i++) {
            int32_t ref = k < STEP_AT ? 0 : step[i];
            int32_t noise = (int32_t)(xorshift32() >> 26) - 32; /* +-32/1024 rad/s */
            in.gyro[i] = (float)(rate[i] + noise) * (1.0f / 1024.0f);
            in.reference[i] = (float)ref * (1.0f / 1024.0f);
            rate[i] += (ref - rate[i]) / 8;
        }
        in.throttle = 1500.0f;
        in.fresh = !(k == 150 || k == 200 || k == 201);
        if (k == 250) in.gyro[1] = NAN;

        KestrelRateOutput out;
        uint32_t t0 = timer1_now(NULL);
        st = LOOP_STEP(&rate_loop, &in, &clock, &out);
        uint32_t t1 = timer1_now(NULL);
        if (st != KESTREL_STATUS_OK) {
            /* Not initialised: the failsafe's pulses, written by the caller. */
            out.pwm[0] = out.pwm[1] = out.pwm[2] = config.safe_esc;
            out.pwm[3] = config.safe_servo;
            out.flags = KESTREL_FLAG_FAILSAFE;
            out.iterations = 0;
            out.kalman_cycles = out.solver_cycles = 0;
        }
        put('P');
        put_u32(k);
        put_u32((uint32_t)st);
        for (uint8_t i = 0; i < 4; i++) put_u32(out.pwm[i]);
        put_u32(out.flags);
        put_u32(out.iterations);
        put_u32(out.kalman_cycles);
        put_u32(out.solver_cycles);
        put_u32(t1 - t0);
        put('\n');
    }

    /* Bad tables, read from flash. */
    KestrelDesign d = design;
    d.values.flash = 0;
    expect("no table address", LOOP_INIT(&rate_loop, &d, &config), KESTREL_STATUS_NULL_POINTER);
    d = design;
    d.kalman16.len -= 2;
    expect("kalman16 short", LOOP_INIT(&rate_loop, &d, &config), KESTREL_STATUS_BAD_SIZE);
    d = design;
    d.checksum ^= 0x8000u;
    expect("checksum", LOOP_INIT(&rate_loop, &d, &config), KESTREL_STATUS_BAD_CHECKSUM);
    d = design;
    d.values.flash += 4; /* the table one value further on: its bytes differ */
    expect("moved table", LOOP_INIT(&rate_loop, &d, &config), KESTREL_STATUS_BAD_CHECKSUM);
    KestrelRateInput in = {{0, 0, 0}, {0, 0, 0}, 1500.0f, 1};
    KestrelRateOutput out;
    expect("step after a failed init", LOOP_STEP(&rate_loop, &in, NULL, &out), KESTREL_STATUS_NOT_INITIALISED);
    put_str("STACK");
    put_u32(stack_peak());
    put('\n');
    put_str("END\n");
    /* Ends the simulation (simavr: sleeping with interrupts off). */
    cli();
    sleep_cpu();
    for (;;) {}
}
