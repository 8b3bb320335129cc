/*
 * A renderer's first contact with strata: load a coated material from TOML
 * text, evaluate a batch of (wi, wo) pairs, draw samples, and check every
 * status. Build (from the repository root):
 *
 *   cargo build --release -p strata-capi
 *   cc -O2 -Icrates/strata-capi/include crates/strata-capi/examples/c/eval_sample.c \
 *      target/release/libstrata_capi.a -lpthread -ldl -lm -o eval_sample
 *   ./eval_sample
 *
 * Directions are in the shading frame (z = normal), both pointing away from
 * the surface; strata normalizes them.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "strata.h"

/* Prints strata's message and exits if a call failed. */
static void check(int32_t status, const char *what) {
    if (status != STRATA_OK) {
        fprintf(stderr, "%s failed (status %d): %s\n", what, status, strata_last_error());
        exit(1);
    }
}

static const char *COATED_COPPER =
    "[[layers]]\n"
    "interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n"
    "medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }\n"
    "[[layers]]\n"
    "interface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.2 }\n";

#define N 4

int main(void) {
    printf("strata %s\n", strata_version());

    /* 256 walks per eval, seed 1. */
    StrataBsdf *bsdf = NULL;
    check(strata_bsdf_from_toml(COATED_COPPER, 256, 1, &bsdf), "strata_bsdf_from_toml");

    /* A batch of N queries, x, y, z per query: light from wi, seen from wo. */
    const float wi[3 * N] = {
        0.0f, 0.0f, 1.0f,
        0.5f, 0.0f, 0.866f,
        0.3f, 0.4f, 0.866f,
        -0.8f, 0.1f, 0.59f,
    };
    const float wo[3 * N] = {
        0.0f, 0.0f, 1.0f,
        -0.5f, 0.0f, 0.866f,
        -0.2f, -0.4f, 0.89f,
        0.7f, 0.0f, 0.71f,
    };
    float f[3 * N], f_err[3 * N], pdf[N];
    uint64_t truncated;
    /* One descriptor per call: the arrays it reads and writes; the fields
     * it does not take stay zero. This eval writes the pdf of the same
     * pairs too (as strata_pdf does), and how many walks the limit of
     * events ended (0 on an ordinary stack). */
    StrataBatch batch = {
        .n = N,
        .wi = {.xyz = wi},
        .wo = {.xyz = wo},
        .f = {.xyz = f},
        .stderr = {.xyz = f_err},
        .pdf = pdf,
        .truncated = &truncated,
    };
    check(strata_eval(bsdf, &batch), "strata_eval");
    printf("eval: f(wi, wo) per channel (no cosine), +- standard error, and pdf "
           "(%llu walks truncated)\n",
           (unsigned long long)truncated);
    for (int k = 0; k < N; k++) {
        printf("  query %d: f = (%.4f, %.4f, %.4f) +- (%.4f, %.4f, %.4f), pdf = %.4f\n", k,
               f[3 * k], f[3 * k + 1], f[3 * k + 2], f_err[3 * k], f_err[3 * k + 1],
               f_err[3 * k + 2], pdf[k]);
        for (int c = 0; c < 3; c++) {
            if (!(f[3 * k + c] >= 0.0f) || !isfinite(f[3 * k + c])) {
                fprintf(stderr, "query %d: f is not a finite nonnegative number\n", k);
                return 1;
            }
        }
    }

    /* One sample per incident direction, keyed by the renderer's own
     * numbers (here: pixel index), so that every call draws fresh noise. */
    StrataSample s[N];
    const uint64_t keys[N] = {1001, 1002, 1003, 1004};
    StrataBatch sampling = {.n = N, .wi = {.xyz = wi}, .keys = keys, .sample = s};
    check(strata_sample(bsdf, &sampling), "strata_sample");
    printf("sample: wo, weight = f |cos| / p, pdf, lobe\n");
    for (int k = 0; k < N; k++) {
        if (s[k].flags == 0) {
            printf("  query %d: absorbed\n", k);
            continue;
        }
        printf("  query %d: wo = (%.3f, %.3f, %.3f), weight = (%.4f, %.4f, %.4f), pdf = %.4f, %s%s\n",
               k, s[k].wo[0], s[k].wo[1], s[k].wo[2], s[k].weight[0], s[k].weight[1],
               s[k].weight[2], s[k].pdf,
               (s[k].flags & STRATA_SAMPLE_REFLECTION) ? "reflection" : "transmission",
               (s[k].flags & STRATA_SAMPLE_DELTA) ? ", delta" : "");
        /* The sample's pdf is the one strata_pdf gives for its direction,
         * so MIS weights agree between strategies. */
        float p;
        StrataBatch one = {.n = 1, .wi = {.xyz = wi + 3 * k}, .wo = {.xyz = s[k].wo}, .pdf = &p};
        check(strata_pdf(bsdf, &one), "strata_pdf");
        if (p != s[k].pdf) {
            fprintf(stderr, "query %d: sample pdf %g != pdf() %g\n", k, s[k].pdf, p);
            return 1;
        }
    }

    /* A bad direction is an error that names the query and the argument. */
    const float bad_wi[3 * 2] = {0.0f, 0.0f, 1.0f, NAN, 0.0f, 1.0f};
    StrataBatch bad = {.n = 2, .wi = {.xyz = bad_wi}, .wo = {.xyz = wo}, .f = {.xyz = f}};
    int32_t status = strata_eval(bsdf, &bad);
    printf("a NaN direction: status %d, \"%s\"\n", status, strata_last_error());
    if (status != STRATA_ERR_INVALID_ARGUMENT) {
        return 1;
    }

    strata_bsdf_free(bsdf);
    return 0;
}
