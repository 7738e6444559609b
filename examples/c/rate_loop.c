/*
 * kestrel rate loop from C: one gyro sample, the rate reference and the
 * throttle in, the four pulses (ESC 1-3, tail servo) out, through the C ABI
 * of kestrel-ffi (kestrel.h) and the tables `kestrel export --lang c` writes
 * (kestrel_design.h / kestrel_design.c).
 *
 * Reads one period per line from standard input:
 *
 *     p q r  p_ref q_ref r_ref  throttle        (rad/s, rad/s, microseconds)
 *
 * and prints the pulses and the loop's flags per line:
 *
 *     pwm1 pwm2 pwm3 servo flags
 *
 * A line "-" is a period without a fresh sample (the loop holds, then goes
 * to its failsafe pulses). `rate_loop --q16` runs the Q15.16 loop instead
 * of the f32 one. Build: see the Makefile here (host) and avr/c-example
 * (ATmega2560, avr-gcc).
 */
#include <stdio.h>
#include <string.h>

#include "kestrel.h"
#include "kestrel_design.h"

/* The loop's state is owned by the caller: static here (1.6 kB). */
static KestrelRateLoopF32 loop_f32;
static KestrelRateLoopQ16 loop_q16;

int main(int argc, char **argv) {
    int q16 = argc > 1 && strcmp(argv[1], "--q16") == 0;
    if (kestrel_abi_version() != KESTREL_ABI_VERSION) {
        fprintf(stderr, "kestrel-ffi ABI %u, header %u\n", kestrel_abi_version(), KESTREL_ABI_VERSION);
        return 2;
    }
    KestrelLoopConfig config;
    kestrel_loop_config_default(&config); /* the thesis's PWM limits and failsafe */
    /* The design's tables in the loop's number format; the library checks
     * their sizes and checksum and refuses a mismatched pair. */
    KestrelDesign design = q16 ? kestrel_design_q16() : kestrel_design_f32();
    KestrelStatus st = q16 ? kestrel_rate_loop_init_fgm_q16(&loop_q16, &design, &config)
                           : kestrel_rate_loop_init_fgm_f32(&loop_f32, &design, &config);
    if (st != KESTREL_STATUS_OK) {
        fprintf(stderr, "rate loop init: status %d\n", (int)st);
        return 1;
    }
    char line[256];
    while (fgets(line, sizeof line, stdin)) {
        KestrelRateInput in;
        memset(&in, 0, sizeof in);
        in.fresh = sscanf(line, "%f %f %f %f %f %f %f", &in.gyro[0], &in.gyro[1], &in.gyro[2],
                          &in.reference[0], &in.reference[1], &in.reference[2],
                          &in.throttle) == 7;
        KestrelRateOutput out;
        /* No clock: no cycle counts on the host (see avr/c-example for one). */
        st = q16 ? kestrel_rate_loop_step_q16(&loop_q16, &in, NULL, &out)
                 : kestrel_rate_loop_step_f32(&loop_f32, &in, NULL, &out);
        if (st != KESTREL_STATUS_OK) {
            fprintf(stderr, "rate loop step: status %d\n", (int)st);
            return 1;
        }
        printf("%u %u %u %u %u\n", out.pwm[0], out.pwm[1], out.pwm[2], out.pwm[3], out.flags);
    }
    return 0;
}
