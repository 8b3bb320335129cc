/*
 * A textured material: a renderer looks up a thickness map at every hit and
 * evaluates the whole batch in one call, each query with its own coat
 * thickness (a StrataColumn of one float per query). Query k then answers
 * bit for bit what a BSDF made from a material file with that thickness
 * answers; this program checks it for every query. Build (from the
 * repository root):
 *
 *   cargo build --release -p strata-capi
 *   cc -O2 -Icrates/strata-capi/include crates/strata-capi/examples/c/textured.c \
 *      target/release/libstrata_capi.a -lpthread -ldl -lm -o textured
 *   ./textured
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "strata.h"

static void check(int32_t status, const char *what) {
    if (status != STRATA_OK) {
        fprintf(stderr, "%s failed (status %d): %s\n", what, status, strata_last_error());
        exit(1);
    }
}

/* The number a column's float `x` sets, as text: the float itself (a
 * thickness column's 0.45f is a material file's 0.449999988079071, the
 * decimal of that float, not 0.45; docs/changes.md). */
static void exact(char *out, size_t size, float x) { snprintf(out, size, "%.17g", (double)x); }

/* The material with a coat of thickness `t`, as a column sets it. */
static void material(char *out, size_t size, float t) {
    char thickness[32];
    exact(thickness, sizeof thickness, t);
    snprintf(out, size,
             "[[layers]]\n"
             "interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n"
             "medium = { thickness = %s, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }\n"
             "[[layers]]\n"
             "interface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.2 }\n",
             thickness);
}

#define N 6
#define SAMPLES 64
#define SEED 9

int main(void) {
    char text[1024];
    material(text, sizeof text, 0.5f);
    StrataBsdf *bsdf = NULL;
    check(strata_bsdf_from_toml(text, SAMPLES, SEED, &bsdf), "strata_bsdf_from_toml");

    /* N hits: the same directions, a thickness from the texture each. */
    float wi[3 * N], wo[3 * N], thickness[N];
    for (int k = 0; k < N; k++) {
        wi[3 * k] = 0.3f, wi[3 * k + 1] = 0.1f, wi[3 * k + 2] = 0.9f;
        wo[3 * k] = -0.4f, wo[3 * k + 1] = 0.2f, wo[3 * k + 2] = 0.8f;
        thickness[k] = 0.05f + 0.4f * (float)k; /* the texture's values */
    }
    StrataColumn columns[1] = {{"layers[0].medium.thickness", 1, thickness}};
    float f[3 * N];
    StrataBatch batch = {
        .n = N,
        .wi = {.xyz = wi},
        .wo = {.xyz = wo},
        .columns = columns,
        .ncolumns = 1,
        .f = {.xyz = f},
    };
    check(strata_eval(bsdf, &batch), "strata_eval");

    printf("textured thickness: f(wi, wo) per query\n");
    for (int k = 0; k < N; k++) {
        /* The same query on a material file with query k's thickness. */
        StrataBsdf *own = NULL;
        material(text, sizeof text, thickness[k]);
        check(strata_bsdf_from_toml(text, SAMPLES, SEED, &own), "strata_bsdf_from_toml");
        float want[3];
        StrataBatch one = {
            .n = 1, .wi = {.xyz = wi + 3 * k}, .wo = {.xyz = wo + 3 * k}, .f = {.xyz = want}};
        check(strata_eval(own, &one), "strata_eval");
        strata_bsdf_free(own);
        printf("  thickness %.2f: f = (%.4f, %.4f, %.4f)\n", (double)thickness[k],
               (double)f[3 * k], (double)f[3 * k + 1], (double)f[3 * k + 2]);
        if (memcmp(want, f + 3 * k, sizeof want) != 0) {
            fprintf(stderr, "query %d differs from its material file\n", k);
            return 1;
        }
    }
    /* The absorbing coat darkens red less than blue as it thickens: blue
     * at the thickest coat is below blue at the thinnest. */
    if (!(f[3 * (N - 1) + 2] < f[2])) {
        fprintf(stderr, "a thicker absorbing coat did not darken blue\n");
        return 1;
    }

    /* An invalid texel stops the batch: nothing is written, and the message
     * names the query, the path and the value. */
    thickness[3] = -1.0f;
    int32_t status = strata_eval(bsdf, &batch);
    printf("a negative thickness: status %d, \"%s\"\n", status, strata_last_error());
    if (status != STRATA_ERR_MATERIAL || strstr(strata_last_error(), "query 3") == NULL) {
        return 1;
    }
    strata_bsdf_free(bsdf);
    return 0;
}
