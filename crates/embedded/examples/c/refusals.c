/*
 * refusals: the C interface's answers to the settings and samples of audit s19 M-1, L-1 and L-2 (and
 * s31 M-6, the PI's plausibility range; s33 H-2, the estimator's), one
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
/* Audit s33 H-2: a ranged estimator, an unranged one and one that never sees the glitch. */
static uint64_t ranged[IPA_HRLS_STATE_BYTES / sizeof(uint64_t)];
static uint64_t unranged[IPA_HRLS_STATE_BYTES / sizeof(uint64_t)];
static uint64_t clean[IPA_HRLS_STATE_BYTES / sizeof(uint64_t)];
static uint64_t before[IPA_HRLS_STATE_BYTES / sizeof(uint64_t)];

/* docs/embedded.md's estimator setup (3, 1, 1), rho = 0.99, UD, no guard. */
static int hrls_paper(void *mem) {
    return ipa_hrls_init(mem, IPA_HRLS_STATE_BYTES, 3, 1, 1, 0.99, 1e6, -1.0, 1.0, 255.0, 0.0,
                         IPA_FORM_UD);
}

/* Sample k of a plant y(k) = 0.5 y(k-1) + x(k-1), deadzone -40/40, slopes 0.012/0.01, commands
 * ((37 k) mod 401) - 200 counts: |y| < 4 mm. */
static double plant_u(int k) { return (double)((37 * k) % 401) - 200.0; }
static double plant_x(double u) {
    return u >= 40.0 ? 0.01 * (u - 40.0) : (u <= -40.0 ? 0.012 * (u + 40.0) : 0.0);
}

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

    /* Audit s33 H-2: the estimator's plausibility range [-5, 205] mm (a 200 mm stroke). On storage
     * not (yet) an estimator: -8; null: -6; crossed or NaN: -1; then kept. */
    printf("hrls_set_range_uninitialised %d\n", ipa_hrls_set_range(ranged, -5.0, 205.0));
    printf("hrls_set_range_null %d\n", ipa_hrls_set_range(NULL, -5.0, 205.0));
    hrls_paper(ranged);
    hrls_paper(unranged);
    hrls_paper(clean);
    printf("hrls_set_range_crossed %d\n", ipa_hrls_set_range(ranged, 205.0, -5.0));
    printf("hrls_set_range_nan %d\n", ipa_hrls_set_range(ranged, NAN, 205.0));
    printf("hrls_set_range %d\n", ipa_hrls_set_range(ranged, -5.0, 205.0));
    printf("hrls_set_range_clean %d\n", ipa_hrls_set_range(clean, -5.0, 205.0));
    /* 40 good samples, the glitch y = 1000 mm at k = 20 to the ranged and unranged estimators: the
     * ranged one refuses it with -9, its storage byte for byte unchanged (1); the unranged one takes
     * it (0). Then a command beyond limit = 255 (u = 300): -9 with the range, taken (0) without. */
    double y = 0.0, u1 = 0.0;
    int bad = 0;
    for (int k = 0; k < 40; k++) {
        double uk = plant_u(k);
        y = 0.5 * y + plant_x(u1);
        u1 = uk;
        if (k == 20) {
            memcpy(before, ranged, sizeof ranged);
            rc = ipa_hrls_update(ranged, uk, 1000.0, NULL);
            printf("hrls_glitch_ranged %d %d\n", rc, memcmp(before, ranged, sizeof ranged) == 0);
            printf("hrls_glitch_unranged %d\n", ipa_hrls_update(unranged, uk, 1000.0, NULL));
        }
        bad += ipa_hrls_update(ranged, uk, y, NULL) != IPA_OK && k >= 3;
        bad += ipa_hrls_update(unranged, uk, y, NULL) != IPA_OK && k >= 3;
        bad += ipa_hrls_update(clean, uk, y, NULL) != IPA_OK && k >= 3;
    }
    /* After the glitch: every update OK (0 failures); the ranged estimator's theta is bit for bit the
     * clean one's (1), the unranged one's is not (0). */
    double th_r[16], th_u[16], th_c[16];
    int n = ipa_hrls_theta(ranged, th_r, 16);
    ipa_hrls_theta(unranged, th_u, 16);
    ipa_hrls_theta(clean, th_c, 16);
    printf("hrls_after_glitch %d %d %d %d\n", bad, n,
           memcmp(th_r, th_c, (size_t)n * sizeof(double)) == 0,
           memcmp(th_u, th_c, (size_t)n * sizeof(double)) == 0);
    memcpy(before, ranged, sizeof ranged);
    rc = ipa_hrls_update(ranged, 300.0, 0.0, NULL);
    printf("hrls_u_beyond_limit_ranged %d %d\n", rc, memcmp(before, ranged, sizeof ranged) == 0);
    printf("hrls_u_beyond_limit_unranged %d\n", ipa_hrls_update(unranged, 300.0, 0.0, NULL));
    /* Why a deadzone is refused: a fresh estimator's theta = 0 has zero slopes (1, no valve
     * deadzone); not an estimator: -8. */
    hrls_paper(hrls);
    printf("hrls_deadzone_reason_fresh %d %d\n", ipa_hrls_deadzone(hrls, &dz),
           ipa_hrls_deadzone_reason(hrls));
    printf("hrls_deadzone_reason_uninitialised %d\n", ipa_hrls_deadzone_reason(before + 1));
    return 0;
}
