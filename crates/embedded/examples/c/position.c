/*
 * position: the tuned position controller of `ipa-sysid tune` (ipa-embedded's C interface), one call
 * per sample, replayed over a recorded closed-loop run.
 *
 *   cc -O2 -std=c99 -Icrates/embedded/include crates/embedded/examples/c/position.c \
 *      target/release/libipa_embedded.a -lm -lpthread -ldl
 *   ./a.out TS KP KI KD TF U_MAX HOLD FINE RESET [B_L B_R M_L M_R [BAND RAMP START REST CUT [REST_BAND [CUT_BAND MIN_RAMP ...]]]] < trace.csv
 *
 * The arguments are the fields of the `controller` object of CONTROLLER.json (ts_s, kp, ki, kd,
 * derivative_filter_s, u_max, hold_band_mm, fine_band_mm, reset_on_crossing as 0/1, and the
 * compensator's deadzone when it has one, then the nudge mode's band_mm, ramp_counts_s, start_fraction,
 * rest_samples, cut_fraction and optionally rest_band_mm, then cut_band_mm and min_ramp_counts_s (0 when absent) when it has one;
 * then the brake's min_step_mm, switch_mm, lead_s, strength, samples, rest_samples and optionally
 * learn and lead_max_s, then release_samples, when it has one; then, after all of these, the
 * short-step approach's max_step_mm, drive_fraction, ramp_counts_s, switch_mm, lead_s,
 * brake_strength, brake_samples and rest_samples, when it has one; then, after all of these, the
 * nudge's creep_step_mm, when it has one; then the brake's rebrake as 0/1, when it has one or the
 * nudge has a slip brake; then the nudge's slip_brake_fraction and slip_brake_samples, when it has
 * them or relearns; then the nudge's relearn as 0/1, then the brake's preview and the short-step approach's
 * preview as 0/1, when it has them; then the short-step approach's breakaway_seed and
 * seed_speed_mm_s, when it has them or the nudge learns its cut fraction; then the nudge's
 * cut_learn as 0/1). trace.csv is what `ipa-sysid control --controller
 * CONTROLLER.json --out trace.csv` writes (header t,r,u,y): the controller is fed r(k) and y(k) of each
 * row, as firmware would feed the set-point and the encoder, and prints its command u(k) per line
 * (round-trip decimal, %.17g), to compare with the u column.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "ipa_embedded.h"

/* The controller state in caller-provided static storage, aligned for double / uint64_t. */
static uint64_t state[IPA_CTL_STATE_BYTES / sizeof(uint64_t) + 1];

int main(int argc, char **argv) {
    if (argc != 10 && argc != 14 && argc != 19 && argc != 20 && argc != 22 && argc != 28 &&
        argc != 30 && argc != 31 && argc != 39 && argc != 40 && argc != 41 && argc != 43 &&
        argc != 44 && argc != 46 && argc != 48 && argc != 49) {
        fprintf(stderr,
                "usage: %s TS KP KI KD TF U_MAX HOLD FINE RESET [B_L B_R M_L M_R [BAND RAMP START REST CUT [REST_BAND [CUT_BAND MIN_RAMP [MIN_STEP SWITCH LEAD STRENGTH SAMPLES BRAKE_REST [LEARN LEAD_MAX [RELEASE [SHORT_MAX_STEP DRIVE RAMP SWITCH LEAD STRENGTH SAMPLES REST [CREEP [REBRAKE [SLIP_BRAKE SLIP_BRAKE_SAMPLES [RELEARN [BRAKE_PREVIEW SHORT_PREVIEW [SEED SEED_SPEED [CUT_LEARN]]]]]]]]]]]]]]]"
                " < trace.csv\n",
                argv[0]);
        return 2;
    }
    IpaController c;
    c.ts = atof(argv[1]);
    c.kp = atof(argv[2]);
    c.ki = atof(argv[3]);
    c.kd = atof(argv[4]);
    c.tf = atof(argv[5]);
    c.u_max = atof(argv[6]);
    c.hold_band = atof(argv[7]);
    c.fine_band = atof(argv[8]);
    c.reset_on_crossing = atoi(argv[9]);
    c.has_deadzone = argc >= 14;
    if (c.has_deadzone) {
        c.deadzone.b_l = atof(argv[10]);
        c.deadzone.b_r = atof(argv[11]);
        c.deadzone.m_l = atof(argv[12]);
        c.deadzone.m_r = atof(argv[13]);
    }
    c.has_nudge = argc >= 19;
    c.nudge_rest_samples = 0;
    c.nudge_band = c.nudge_ramp = c.nudge_start_fraction = c.nudge_cut_fraction = 0.0;
    c.nudge_rest_band = 0.0;
    c.nudge_cut_band = c.nudge_min_ramp = 0.0;
    /* The creep limit: off (0) unless given, as in a struct zeroed before it existed. */
    c.nudge_creep_step = argc >= 40 ? atof(argv[39]) : 0.0;
    /* The brake's re-brake (0/1): off unless given, as in a struct zeroed before it existed. */
    c.brake_rebrake = argc >= 41 ? atoi(argv[40]) : 0;
    /* The slip brake: off (0) unless given, as in a struct zeroed before it existed. */
    c.nudge_slip_brake = argc >= 43 ? atof(argv[41]) : 0.0;
    c.nudge_slip_brake_samples = argc >= 43 ? (uint32_t)atol(argv[42]) : 0;
    /* The nudge's relearning (0/1) and the previews (0/1): off unless given, as in a struct zeroed
     * before they existed. */
    c.nudge_relearn = argc >= 44 ? atoi(argv[43]) : 0;
    c.brake_preview = argc >= 46 ? atoi(argv[44]) : 0;
    c.short_preview = argc >= 46 ? atoi(argv[45]) : 0;
    /* The short-step approach's breakaway seed: off (0) unless given, as in a struct zeroed before
     * it existed. */
    c.short_seed = argc >= 48 ? atof(argv[46]) : 0.0;
    c.short_seed_speed = argc >= 48 ? atof(argv[47]) : 0.0;
    /* The held nudge's learnt cut fraction (0/1): off unless given, as in a struct zeroed before it
     * existed. */
    c.nudge_cut_learn = argc == 49 ? atoi(argv[48]) : 0;
    if (c.has_nudge) {
        c.nudge_band = atof(argv[14]);
        c.nudge_ramp = atof(argv[15]);
        c.nudge_start_fraction = atof(argv[16]);
        c.nudge_rest_samples = (uint32_t)atol(argv[17]);
        c.nudge_cut_fraction = atof(argv[18]);
        if (argc >= 20) c.nudge_rest_band = atof(argv[19]);
        if (argc >= 22) {
            c.nudge_cut_band = atof(argv[20]);
            c.nudge_min_ramp = atof(argv[21]);
        }
    }
    c.has_brake = argc >= 28;
    c.brake_samples = c.brake_rest_samples = 0;
    c.brake_min_step = c.brake_switch = c.brake_lead = c.brake_strength = 0.0;
    c.brake_learn = c.brake_lead_max = 0.0;
    c.brake_release = 0;
    if (c.has_brake) {
        c.brake_min_step = atof(argv[22]);
        c.brake_switch = atof(argv[23]);
        c.brake_lead = atof(argv[24]);
        c.brake_strength = atof(argv[25]);
        c.brake_samples = (uint32_t)atol(argv[26]);
        c.brake_rest_samples = (uint32_t)atol(argv[27]);
        if (argc >= 30) {
            c.brake_learn = atof(argv[28]);
            c.brake_lead_max = atof(argv[29]);
        }
        if (argc >= 31) c.brake_release = (uint32_t)atol(argv[30]);
    }
    /* The short-step approach: off (max step 0) unless given, as in a struct zeroed before it existed. */
    c.short_samples = c.short_rest_samples = 0;
    c.short_max_step = c.short_drive_fraction = c.short_ramp = 0.0;
    c.short_switch = c.short_lead = c.short_strength = 0.0;
    if (argc >= 39) {
        c.short_max_step = atof(argv[31]);
        c.short_drive_fraction = atof(argv[32]);
        c.short_ramp = atof(argv[33]);
        c.short_switch = atof(argv[34]);
        c.short_lead = atof(argv[35]);
        c.short_strength = atof(argv[36]);
        c.short_samples = (uint32_t)atol(argv[37]);
        c.short_rest_samples = (uint32_t)atol(argv[38]);
    }
    int rc = ipa_ctl_init(state, sizeof state, &c);
    if (rc != IPA_OK) {
        fprintf(stderr, "ipa_ctl_init: error %d\n", rc);
        return 1;
    }
    char line[512];
    if (fgets(line, sizeof line, stdin) == NULL) {
        fprintf(stderr, "empty input: expected the header t,r,u,y\n");
        return 2;
    }
    double t, r, u_rec, y, u;
    long k = 0;
    while (fgets(line, sizeof line, stdin) != NULL) {
        if (sscanf(line, "%lf,%lf,%lf,%lf", &t, &r, &u_rec, &y) != 4) {
            fprintf(stderr, "line %ld: expected t,r,u,y\n", k + 2);
            return 2;
        }
        rc = ipa_ctl_step(state, r, y, &u);
        if (rc != IPA_OK) {
            fprintf(stderr, "ipa_ctl_step at sample %ld: error %d\n", k, rc);
            return 1;
        }
        printf("%.17g\n", u);
        k++;
    }
    return 0;
}
