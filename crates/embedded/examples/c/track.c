/*
 * track: the paper's recursive Hammerstein estimator (ipa-embedded's C interface) over a CSV record.
 *
 *   cc -O2 -std=c99 -Icrates/embedded/include crates/embedded/examples/c/track.c \
 *      target/release/libipa_embedded.a -lm -lpthread -ldl
 *   ./a.out NA NB NK FORGETTING [P0 [FORM]] < data.csv
 *
 * data.csv has a header row naming (at least) the columns u (PWM counts) and y (mm); other columns,
 * such as t, are ignored. The estimate starts, as `ipa-sysid identify --method rls --passes 1` does,
 * from breakpoints at the record's smallest commands (ipa_hrls_record_start), so it reads the whole
 * record first; firmware would call ipa_hrls_init with b_l0 = -1, b_r0 = 1, limit = 255 instead and
 * ipa_hrls_update once per sample. P0 (default 1e6) is identify's --p0; FORM is "standard" (the paper's
 * eq. 12, default) or "ud" (Bierman's factors, identify --rls-form ud). At the end it prints one JSON
 * object with the fitted model:
 *   {"b_l":..,"b_r":..,"m_l":..,"m_r":..,"a":[..],"b":[..]}
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include "ipa_embedded.h"

/* The estimator state in caller-provided static storage, aligned for double / uint64_t. */
static uint64_t state[IPA_HRLS_STATE_BYTES / sizeof(uint64_t) + 1];

static int column(const char *header, const char *name) {
    char buf[4096];
    strncpy(buf, header, sizeof buf - 1);
    buf[sizeof buf - 1] = '\0';
    int i = 0;
    for (char *tok = strtok(buf, ",\r\n"); tok != NULL; tok = strtok(NULL, ",\r\n"), i++) {
        while (*tok == ' ' || *tok == '"') tok++;
        size_t n = strlen(tok);
        while (n > 0 && (tok[n - 1] == ' ' || tok[n - 1] == '"')) tok[--n] = '\0';
        if (strcmp(tok, name) == 0) return i;
    }
    return -1;
}

/* Field `col` of a CSV line as a double; returns 0 when missing or not a number. */
static int field(const char *line, int col, double *out) {
    const char *p = line;
    for (int i = 0; i < col; i++) {
        p = strchr(p, ',');
        if (p == NULL) return 0;
        p++;
    }
    char *end;
    *out = strtod(p, &end);
    return end != p;
}

static void print_number(double v) {
    if (isfinite(v)) printf("%.17g", v); else printf("null");
}

static void print_array(const char *name, const double *v, int n) {
    printf("\"%s\":[", name);
    for (int i = 0; i < n; i++) {
        if (i > 0) printf(",");
        print_number(v[i]);
    }
    printf("]");
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s NA NB NK FORGETTING [P0 [standard|ud]] < data.csv\n", argv[0]);
        return 2;
    }
    unsigned na = (unsigned)atoi(argv[1]), nb = (unsigned)atoi(argv[2]), nk = (unsigned)atoi(argv[3]);
    double rho = strtod(argv[4], NULL);
    double p0 = argc > 5 ? strtod(argv[5], NULL) : 1e6;
    uint32_t form = IPA_FORM_STANDARD;
    if (argc > 6) {
        if (strcmp(argv[6], "ud") == 0) {
            form = IPA_FORM_UD;
        } else if (strcmp(argv[6], "standard") != 0) {
            fprintf(stderr, "FORM must be standard or ud\n");
            return 2;
        }
    }

    char line[4096];
    if (fgets(line, sizeof line, stdin) == NULL) {
        fprintf(stderr, "empty input\n");
        return 1;
    }
    int ucol = column(line, "u"), ycol = column(line, "y");
    if (ucol < 0 || ycol < 0) {
        fprintf(stderr, "the header needs columns u and y\n");
        return 1;
    }
    size_t n = 0, cap = 4096;
    double *u = malloc(cap * sizeof *u), *y = malloc(cap * sizeof *y);
    if (u == NULL || y == NULL) return 1;
    size_t lineno = 1; /* the header was line 1 */
    while (fgets(line, sizeof line, stdin) != NULL) {
        lineno++;
        if (line[0] == '\n' || line[0] == '\r' || line[0] == '\0') continue;
        if (n == cap) {
            cap *= 2;
            double *nu = realloc(u, cap * sizeof *u), *ny = realloc(y, cap * sizeof *y);
            if (nu == NULL || ny == NULL) return 1;
            u = nu;
            y = ny;
        }
        if (!field(line, ucol, &u[n]) || !field(line, ycol, &y[n])) {
            fprintf(stderr, "line %zu: u or y is not a number\n", lineno);
            return 1;
        }
        /* strtod reads "nan" and "inf": the library would refuse them with IPA_ERR_NOT_FINITE (-3:
           ipa_hrls_record_start for a command, ipa_hrls_update for the sample), naming no line; the
           line is named here. */
        if (!isfinite(u[n]) || !isfinite(y[n])) {
            fprintf(stderr, "line %zu: u = %g, y = %g: not finite\n", lineno, u[n], y[n]);
            return 1;
        }
        n++;
    }

    double b_l0, b_r0, limit;
    int rc = ipa_hrls_record_start(u, n, &b_l0, &b_r0, &limit);
    if (rc != IPA_OK) {
        fprintf(stderr, "ipa_hrls_record_start failed: %d\n", rc);
        return 1;
    }
    rc = ipa_hrls_init(state, sizeof state, na, nb, nk, rho, p0, b_l0, b_r0, limit, 0.0, form);
    if (rc != IPA_OK) {
        fprintf(stderr, "ipa_hrls_init failed: %d\n", rc);
        return 1;
    }
    for (size_t k = 0; k < n; k++) {
        double eps;
        rc = ipa_hrls_update(state, u[k], y[k], &eps);
        if (rc < 0) {
            fprintf(stderr, "ipa_hrls_update failed at sample %zu: %d\n", k, rc);
            return 1;
        }
    }

    IpaDeadzone dz;
    double a[IPA_MAX_NA], b[IPA_MAX_NB];
    int got_a = ipa_hrls_a(state, a, IPA_MAX_NA), got_b = ipa_hrls_b(state, b, IPA_MAX_NB);
    int dz_rc = ipa_hrls_deadzone(state, &dz);
    if (dz_rc < 0 || got_a < 0 || got_b < 0) {
        fprintf(stderr, "reading the model failed\n");
        return 1;
    }
    if (dz_rc == IPA_NOT_PHYSICAL) {
        /* Written, but no valve deadzone yet (b_l > 0, b_r < 0 or a slope <= 0): not for compensation. */
        fprintf(stderr, "warning: the deadzone estimate is no valve deadzone (b_l > 0, b_r < 0 or a slope <= 0); "
                        "do not compensate with it: more exciting samples are needed\n");
    }
    printf("{\"b_l\":");
    print_number(dz.b_l);
    printf(",\"b_r\":");
    print_number(dz.b_r);
    printf(",\"m_l\":");
    print_number(dz.m_l);
    printf(",\"m_r\":");
    print_number(dz.m_r);
    printf(",");
    print_array("a", a, got_a);
    printf(",");
    print_array("b", b, got_b);
    printf("}\n");
    free(u);
    free(y);
    return 0;
}
