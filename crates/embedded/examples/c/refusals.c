/*
 * refusals: the C interface's answers to the settings and samples of audit s19 M-1, L-1 and L-2 (and
 * s31 M-6, the PI's plausibility range), one
 * line per case: NAME RC [VALUES...] (doubles as round-trip decimals, %.17g). Outputs are preset to 42
 * so that a line shows whether a refused call wrote them. Checked by
 * `c_interface_refuses_the_audit_s19_cases` (crates/cli/tests/embedded_c.rs).
 *
 *   cc -O2 -std=c99 -Icrates/embedded/include crates/embedded/examples/c/refusals.c \
 *      target/release/libipa_embedded.a -lm -lpthread -ldl
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "ipa_embedded.h"

static uint64_t ctl[IPA_CTL_STATE_BYTES / sizeof(uint64_t)];
static uint64_t pi[IPA_PI_STATE_BYTES / sizeof(uint64_t)];
static uint64_t hrls[IPA_HRLS_STATE_BYTES / sizeof(uint64_t)];

/* A plain P controller, Kp = 3 counts/mm, u_max = 255 (every other field 0: no deadzone, nudge,
 * brake or short-step approach), sampled at ts. */
static IpaController p_only(double ts) {
    IpaController c;
    memset(&c, 0, sizeof c);
    c.ts = ts;
    c.kp = 3.0;
    c.u_max = 255.0;
    return c;
}

static int hrls_init(double b_l0, double b_r0) {
    return ipa_hrls_init(hrls, sizeof hrls, 3, 1, 1, 1.0, 1e6, b_l0, b_r0, 255.0, 0.0,
                         IPA_FORM_STANDARD);
}

int main(void) {
    double u, bl, br, lim;
    int rc;

    /* M-1: the audit's subnormal Ts, and the floor itself. */
    IpaController c = p_only(1e-310);
    printf("ctl_init_ts_1e-310 %d\n", ipa_ctl_init(ctl, sizeof ctl, &c));
    c = p_only(1e-6);
    printf("ctl_init_ts_1e-6 %d\n", ipa_ctl_init(ctl, sizeof ctl, &c));
    /* M-1, the guard: r = 50; y = 0, then a jump to 1e308 (the velocity overflows), then y = 1. */
    c = p_only(0.01);
    printf("ctl_init_ts_0.01 %d\n", ipa_ctl_init(ctl, sizeof ctl, &c));
    const double ys[3] = {0.0, 1e308, 1.0};
    for (int k = 0; k < 3; k++) {
        u = 42.0;
        rc = ipa_ctl_step(ctl, 50.0, ys[k], &u);
        printf("ctl_step_%d %d %.17g\n", k, rc, u);
    }
    /* The PI step: Kp = 0, e = 1e308 - (-1e308) overflows, Kp e = 0 * inf. */
    printf("pi_init %d\n", ipa_pi_init(pi, sizeof pi, 0.0, 1.0, 0.01, 255.0, 0, 0.0));
    u = 42.0;
    rc = ipa_pi_step(pi, 1e308, -1e308, &u);
    printf("pi_step_overflow %d %.17g\n", rc, u);

    /* Audit s31 M-6: the back-calculation PI (Kp = 14, Ki = 1, Ts = 0.01 s, Tt = 14 s), 100 samples at
     * r = 50, y = 49.9, one glitch y = -1e6, then y = 49.9 again: with the range [0, 200] set (pi) and
     * without one (pi2); pi3 never sees the glitch. Bad ranges first. */
    static uint64_t pi2[IPA_PI_STATE_BYTES / sizeof(uint64_t)];
    static uint64_t pi3[IPA_PI_STATE_BYTES / sizeof(uint64_t)];
    printf("pi_set_range_uninitialised %d\n", ipa_pi_set_range(pi2, 0.0, 200.0));
    ipa_pi_init(pi, sizeof pi, 14.0, 1.0, 0.01, 255.0, 2, 14.0);
    ipa_pi_init(pi2, sizeof pi2, 14.0, 1.0, 0.01, 255.0, 2, 14.0);
    ipa_pi_init(pi3, sizeof pi3, 14.0, 1.0, 0.01, 255.0, 2, 14.0);
    printf("pi_set_range_null %d\n", ipa_pi_set_range(NULL, 0.0, 200.0));
    printf("pi_set_range_crossed %d\n", ipa_pi_set_range(pi, 200.0, 0.0));
    printf("pi_set_range_nan %d\n", ipa_pi_set_range(pi, NAN, 200.0));
    printf("pi_set_range %d\n", ipa_pi_set_range(pi, 0.0, 200.0));
    double u2, u3;
    for (int k = 0; k < 100; k++) {
        ipa_pi_step(pi, 50.0, 49.9, &u);
        ipa_pi_step(pi2, 50.0, 49.9, &u2);
        ipa_pi_step(pi3, 50.0, 49.9, &u3);
    }
    u = u2 = 42.0;
    rc = ipa_pi_step(pi, 50.0, -1e6, &u);
    printf("pi_glitch_ranged %d %.17g\n", rc, u);
    rc = ipa_pi_step(pi2, 50.0, -1e6, &u2);
    printf("pi_glitch_unranged %d %.17g\n", rc, u2);
    u = 42.0;
    rc = ipa_pi_step(pi, 250.0, 49.9, &u);
    printf("pi_set_point_out_of_range %d %.17g\n", rc, u);
    /* The next sample: the ranged controller as the one that never saw the glitch, the other negative. */
    int rc2, rc3;
    rc = ipa_pi_step(pi, 50.0, 49.9, &u);
    rc2 = ipa_pi_step(pi2, 50.0, 49.9, &u2);
    rc3 = ipa_pi_step(pi3, 50.0, 49.9, &u3);
    printf("pi_after_glitch %d %d %d %.17g %.17g %.17g\n", rc, rc2, rc3, u, u2, u3);

    /* The tuned controller (P only, Kp = 3) with the range [0, 200]: y = -1e6 is refused with u not
     * written, then y = 1 gives 3 x 49 = 147. */
    c = p_only(0.01);
    ipa_ctl_init(ctl, sizeof ctl, &c);
    printf("ctl_set_range_crossed %d\n", ipa_ctl_set_range(ctl, 200.0, 0.0));
    printf("ctl_set_range %d\n", ipa_ctl_set_range(ctl, 0.0, 200.0));
    u = 42.0;
    rc = ipa_ctl_step(ctl, 50.0, -1e6, &u);
    printf("ctl_glitch_ranged %d %.17g\n", rc, u);
    rc = ipa_ctl_step(ctl, 50.0, 1.0, &u);
    printf("ctl_after_glitch %d %.17g\n", rc, u);

    /* L-1: the deadzone inverse of a NaN / inf controller output, and of u = 5. */
    IpaDeadzone dz = {-10.0, 10.0, 0.5, 0.5};
    u = 42.0;
    rc = ipa_dz_compensate(&dz, 0, 0.0, 255.0, NAN, &u);
    printf("dz_nan %d %.17g\n", rc, u);
    u = 42.0;
    rc = ipa_dz_compensate(&dz, 0, 0.0, 255.0, -INFINITY, &u);
    printf("dz_minus_inf %d %.17g\n", rc, u);
    u = 42.0;
    rc = ipa_dz_compensate(&dz, 0, 0.0, 255.0, 5.0, &u);
    printf("dz_5 %d %.17g\n", rc, u);

    /* L-1: the record start with a NaN, with infinities, and a finite record. */
    const double nan_u[3] = {NAN, 1.0, -1.0};
    const double inf_u[3] = {INFINITY, -0.0, -INFINITY};
    const double fine_u[5] = {0.0, 30.0, -7.0, 12.0, -100.0};
    bl = br = lim = 42.0;
    rc = ipa_hrls_record_start(nan_u, 3, &bl, &br, &lim);
    printf("record_start_nan %d %.17g %.17g %.17g\n", rc, bl, br, lim);
    rc = ipa_hrls_record_start(inf_u, 3, &bl, &br, &lim);
    printf("record_start_inf %d %.17g %.17g %.17g\n", rc, bl, br, lim);
    rc = ipa_hrls_record_start(fine_u, 5, &bl, &br, &lim);
    printf("record_start_finite %d %.17g %.17g %.17g\n", rc, bl, br, lim);

    /* L-2: initial breakpoints outside b_l0 <= 0 <= b_r0, and the one-sided record's. */
    printf("hrls_init_bl0_1 %d\n", hrls_init(1.0, 1.0));
    printf("hrls_init_crossed_inf %d\n", hrls_init(INFINITY, -INFINITY));
    printf("hrls_init_one_sided %d\n", hrls_init(-INFINITY, INFINITY));
    return 0;
}
