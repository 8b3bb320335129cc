/*
 * The C ABI under bad input: NULL pointers, empty and huge batches, NaN and
 * zero directions, malformed and invalid materials. Every check compares the
 * status and looks for the argument (and query index) in strata_last_error().
 * Exits 1 if any check fails. Built and run by .ci/capi.sh.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "strata.h"

static int failures = 0;
static int checks = 0;

/* Checks that a call returned `want` and that the last error contains each
 * of the (up to two) fragments. */
static void expect(const char *what, int32_t got, int32_t want, const char *frag1,
                   const char *frag2) {
    const char *msg = strata_last_error();
    int ok = got == want && msg != NULL;
    if (ok && frag1 != NULL && strstr(msg, frag1) == NULL) ok = 0;
    if (ok && frag2 != NULL && strstr(msg, frag2) == NULL) ok = 0;
    if (ok && want == STRATA_OK && msg[0] != '\0') ok = 0;
    checks++;
    if (!ok) {
        failures++;
        fprintf(stderr, "FAIL %s: status %d (want %d), message \"%s\"\n", what, got, want,
                msg ? msg : "(NULL)");
    }
}

static const char *GOOD =
    "[[layers]]\n"
    "interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n"
    "medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }\n"
    "[[layers]]\n"
    "interface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.2 }\n";

int main(void) {
    StrataBsdf *b = NULL;
    expect("good material", strata_bsdf_from_toml(GOOD, 16, 3, &b), STRATA_OK, NULL, NULL);
    if (b == NULL) {
        fprintf(stderr, "FAIL: no BSDF from a good material\n");
        return 1;
    }

    float wi[12] = {0, 0, 1, 0.5f, 0, 0.8f, 0.1f, 0.2f, 0.9f, -0.3f, 0, 1};
    float wo[12] = {0, 0, 1, -0.5f, 0, 0.8f, 0.2f, 0.1f, 0.9f, 0.3f, 0.1f, 1};
    float f[12], se[12], pdf[4];
    uint64_t keys[4] = {1, 2, 3, 4};
    StrataSample s[4];
    StrataAlbedo a[4];

    /* ---- NULL BSDF */
    expect("eval, NULL b", strata_eval_batch(NULL, 4, wi, wo, f, NULL), STRATA_ERR_NULL,
           "b is NULL", "strata_eval_batch");
    expect("sample, NULL b", strata_sample_batch(NULL, 4, wi, NULL, s), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("pdf, NULL b", strata_pdf_batch(NULL, 4, wi, wo, pdf), STRATA_ERR_NULL, "b is NULL",
           NULL);
    expect("albedo, NULL b", strata_albedo_batch(NULL, 4, wi, 8, NULL, a), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("transport, NULL b", strata_bsdf_set_transport(NULL, 0), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("estimator, NULL b", strata_bsdf_set_estimator(NULL, 0), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("pdf samples, NULL b", strata_bsdf_set_pdf_samples(NULL, 4), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("pdf walks, NULL b", strata_bsdf_set_pdf_walks(NULL, 8, 128, 0.1), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("NULL b even with n = 0", strata_eval_batch(NULL, 0, NULL, NULL, NULL, NULL),
           STRATA_ERR_NULL, "b is NULL", NULL);
    expect("keyed, NULL b and keys", strata_eval_batch_keyed(NULL, 4, wi, wo, NULL, f, NULL),
           STRATA_ERR_NULL, "b is NULL", NULL);
    expect("threads, NULL b", strata_bsdf_set_threads(NULL, 1), STRATA_ERR_NULL, "b is NULL",
           NULL);
    StrataStackInfo info;
    expect("info, NULL b", strata_bsdf_info(NULL, &info), STRATA_ERR_NULL, "b is NULL", NULL);
    expect("info, NULL out", strata_bsdf_info(b, NULL), STRATA_ERR_NULL, "out is NULL", NULL);
    uint32_t exact;
    expect("exact, NULL b", strata_bsdf_is_exact(NULL, &exact), STRATA_ERR_NULL, "b is NULL",
           NULL);
    expect("exact, NULL out", strata_bsdf_is_exact(b, NULL), STRATA_ERR_NULL, "out is NULL",
           NULL);
    expect("without walks, NULL b", strata_bsdf_eval_without_walks(NULL, &exact), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("without walks, NULL out", strata_bsdf_eval_without_walks(b, NULL), STRATA_ERR_NULL,
           "out is NULL", NULL);
    expect("too many threads", strata_bsdf_set_threads(b, 5000), STRATA_ERR_INVALID_ARGUMENT,
           "threads = 5000", NULL);
    strata_bsdf_free(NULL); /* a no-op */

    /* ---- NULL arrays, n > 0: the message names the argument and n */
    expect("eval, NULL wi", strata_eval_batch(b, 4, NULL, wo, f, NULL), STRATA_ERR_NULL,
           "wi is NULL (n = 4)", NULL);
    expect("eval, NULL wo", strata_eval_batch(b, 4, wi, NULL, f, NULL), STRATA_ERR_NULL,
           "wo is NULL (n = 4)", NULL);
    expect("eval, NULL f_out", strata_eval_batch(b, 4, wi, wo, NULL, NULL), STRATA_ERR_NULL,
           "f_out is NULL (n = 4)", NULL);
    expect("eval keyed, NULL keys", strata_eval_batch_keyed(b, 4, wi, wo, NULL, f, NULL),
           STRATA_ERR_NULL, "keys is NULL (n = 4)", NULL);
    expect("sample, NULL wi", strata_sample_batch(b, 4, NULL, keys, s), STRATA_ERR_NULL,
           "wi is NULL (n = 4)", "strata_sample_batch");
    expect("sample, NULL out", strata_sample_batch(b, 4, wi, keys, NULL), STRATA_ERR_NULL,
           "out is NULL (n = 4)", NULL);
    expect("pdf, NULL pdf_out", strata_pdf_batch(b, 4, wi, wo, NULL), STRATA_ERR_NULL,
           "pdf_out is NULL (n = 4)", NULL);
    expect("albedo, NULL out", strata_albedo_batch(b, 4, wi, 8, NULL, NULL), STRATA_ERR_NULL,
           "out is NULL (n = 4)", NULL);
    expect("eval soa, NULL wi_y",
           strata_eval_batch_soa(b, 4, wi, NULL, wi, wo, wo, wo, NULL, f, f + 4, f + 8, NULL,
                                 NULL, NULL),
           STRATA_ERR_NULL, "wi_y is NULL (n = 4)", NULL);
    expect("eval soa, one stderr array",
           strata_eval_batch_soa(b, 4, wi, wi + 4, wi + 8, wo, wo + 4, wo + 8, NULL, f, f + 4,
                                 f + 8, se, NULL, NULL),
           STRATA_ERR_NULL, "se_g is NULL", "pass all three or none");
    expect("sample soa, NULL flags",
           strata_sample_batch_soa(b, 4, wi, wi + 4, wi + 8, NULL, f, f + 4, f + 8, se, se + 4,
                                   se + 8, pdf, NULL),
           STRATA_ERR_NULL, "flags is NULL (n = 4)", NULL);

    /* ---- n = 0 does nothing, whatever the arrays */
    expect("eval, n = 0", strata_eval_batch(b, 0, NULL, NULL, NULL, NULL), STRATA_OK, NULL,
           NULL);
    expect("eval keyed, n = 0", strata_eval_batch_keyed(b, 0, NULL, NULL, NULL, NULL, NULL),
           STRATA_OK, NULL, NULL);
    expect("sample, n = 0", strata_sample_batch(b, 0, NULL, NULL, NULL), STRATA_OK, NULL, NULL);
    expect("pdf, n = 0", strata_pdf_batch(b, 0, NULL, NULL, NULL), STRATA_OK, NULL, NULL);
    expect("albedo, n = 0", strata_albedo_batch(b, 0, NULL, 8, NULL, NULL), STRATA_OK, NULL,
           NULL);
    expect("eval soa, n = 0",
           strata_eval_batch_soa(b, 0, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL,
                                 NULL, NULL, NULL, NULL),
           STRATA_OK, NULL, NULL);
    expect("sample soa, n = 0",
           strata_sample_batch_soa(b, 0, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL,
                                   NULL, NULL, NULL),
           STRATA_OK, NULL, NULL);

    /* ---- huge n: an error, not a crash */
    expect("eval, huge n, NULL", strata_eval_batch(b, SIZE_MAX, NULL, wo, f, NULL),
           STRATA_ERR_NULL, "wi is NULL", NULL);
    expect("eval, huge n", strata_eval_batch(b, SIZE_MAX / 2, wi, wo, f, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "too large", NULL);

    /* ---- bad directions: the message names the query and the argument */
    float bad[12];
    memcpy(bad, wi, sizeof bad);
    bad[6] = NAN; /* query 2, wi.x */
    for (int i = 0; i < 12; i++) f[i] = -7.0f;
    expect("eval, NaN wi", strata_eval_batch(b, 4, bad, wo, f, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "query 2: wi = [NaN", "must be finite");
    int untouched = 1;
    for (int i = 0; i < 12; i++) untouched &= f[i] == -7.0f;
    checks++;
    if (!untouched) {
        failures++;
        fprintf(stderr, "FAIL: a failed eval wrote to f_out\n");
    }
    expect("sample, NaN wi", strata_sample_batch(b, 4, bad, NULL, s),
           STRATA_ERR_INVALID_ARGUMENT, "query 2: wi = [NaN", NULL);
    expect("albedo, NaN wi", strata_albedo_batch(b, 4, bad, 8, NULL, a),
           STRATA_ERR_INVALID_ARGUMENT, "query 2: wi", NULL);
    memcpy(bad, wo, sizeof bad);
    bad[3] = bad[4] = bad[5] = 0.0f; /* query 1, wo = 0 */
    expect("eval, zero wo", strata_eval_batch(b, 4, wi, bad, f, se),
           STRATA_ERR_INVALID_ARGUMENT, "query 1: wo = [0, 0, 0]", "zero length");
    expect("pdf, zero wo", strata_pdf_batch(b, 4, wi, bad, pdf), STRATA_ERR_INVALID_ARGUMENT,
           "query 1: wo = [0, 0, 0]", NULL);
    bad[3] = INFINITY;
    expect("eval keyed, infinite wo", strata_eval_batch_keyed(b, 4, wi, bad, keys, f, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "query 1: wo = [inf", NULL);

    /* ---- other bad arguments */
    expect("albedo, 0 walks", strata_albedo_batch(b, 4, wi, 0, NULL, a),
           STRATA_ERR_INVALID_ARGUMENT, "walks = 0", NULL);
    expect("transport 7", strata_bsdf_set_transport(b, 7), STRATA_ERR_INVALID_ARGUMENT,
           "mode = 7", NULL);
    expect("estimator 3", strata_bsdf_set_estimator(b, 3), STRATA_ERR_INVALID_ARGUMENT,
           "estimator = 3", NULL);
    expect("pdf walks, pilot 1", strata_bsdf_set_pdf_walks(b, 1, 64, 0.1),
           STRATA_ERR_INVALID_ARGUMENT, "pilot = 1", NULL);
    expect("pdf walks, NaN error", strata_bsdf_set_pdf_walks(b, 8, 64, NAN),
           STRATA_ERR_INVALID_ARGUMENT, "rel_stderr = NaN", NULL);
    expect("overlapping arrays", strata_eval_batch(b, 4, wi, wo, (float *)wi, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "wi and f_out overlap", NULL);
    char raw[64];
    expect("misaligned wi", strata_eval_batch(b, 1, (const float *)(raw + 1), wo, f, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "not aligned", NULL);

    /* ---- per-query columns: the message names the column or query, the
     * path and the value; nothing is written */
    const float thick[4] = {0.1f, 0.2f, -0.5f, 0.4f}; /* query 2 is invalid */
    const float good_thick[4] = {0.1f, 0.2f, 0.3f, 0.4f};
    StrataColumn col = {"layers[0].medium.thickness", 1, good_thick};
    expect("columns, NULL array",
           strata_eval_batch_columns(b, 4, wi, wo, NULL, 1, f, NULL), STRATA_ERR_NULL,
           "columns is NULL (ncolumns = 1)", "strata_eval_batch_columns");
    col.path = NULL;
    expect("columns, NULL path", strata_eval_batch_columns(b, 4, wi, wo, &col, 1, f, NULL),
           STRATA_ERR_NULL, "columns[0].path is NULL", NULL);
    col.path = "layers[0].medium.thickness";
    col.values = NULL;
    expect("columns, NULL values", strata_sample_batch_columns(b, 4, wi, NULL, &col, 1, s),
           STRATA_ERR_NULL, "columns[0].values is NULL (n = 4)", "strata_sample_batch_columns");
    col.values = good_thick;
    col.width = 2;
    expect("columns, width 2", strata_pdf_batch_columns(b, 4, wi, wo, &col, 1, pdf),
           STRATA_ERR_INVALID_ARGUMENT, "columns[0].width = 2", "layers[0].medium.thickness");
    col.width = 1;
    col.path = "layers[0].medium.kind";
    expect("columns, not a settable path",
           strata_albedo_batch_columns(b, 4, wi, 8, NULL, &col, 1, a),
           STRATA_ERR_INVALID_ARGUMENT, "columns[0]", "layers[0].medium.kind");
    col.path = "layers[0].medium.thick\xffness";
    expect("columns, path not UTF-8", strata_eval_batch_columns(b, 4, wi, wo, &col, 1, f, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "columns[0].path is not UTF-8", NULL);
    col.path = "layers[0].medium.thickness";
    col.values = thick;
    for (int i = 0; i < 12; i++) f[i] = -7.0f;
    expect("columns, negative thickness at query 2",
           strata_eval_batch_columns(b, 4, wi, wo, &col, 1, f, se), STRATA_ERR_MATERIAL,
           "query 2: set `layers[0].medium.thickness` = -0.5",
           "layer 0: medium.thickness = -0.5");
    untouched = 1;
    for (int i = 0; i < 12; i++) untouched &= f[i] == -7.0f;
    checks++;
    if (!untouched) {
        failures++;
        fprintf(stderr, "FAIL: a failed eval with columns wrote to f_out\n");
    }
    const float nan_sigma[12] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, NAN, 1}; /* query 3 */
    StrataColumn two[2] = {{"layers[0].medium.thickness", 1, good_thick},
                           {"layers[0].medium.sigma_t", 3, nan_sigma}};
    expect("columns, NaN sigma_t at query 3",
           strata_pdf_unbiased_batch_columns(b, 4, wi, wo, 8, two, 2, pdf, se),
           STRATA_ERR_INVALID_ARGUMENT, "query 3: set `layers[0].medium.sigma_t` = NaN",
           "not a finite number");
    for (int i = 0; i < 12; i++) f[i] = 0.3f;
    StrataColumn in_f = {"layers[0].medium.thickness", 1, f}; /* f is also f_out */
    expect("columns, overlapping an output",
           strata_eval_batch_keyed_columns(b, 4, wi, wo, keys, &in_f, 1, f, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "f_out and columns[0].values overlap", NULL);
    expect("columns, n = 0", strata_eval_batch_columns(b, 0, NULL, NULL, NULL, 3, NULL, NULL),
           STRATA_OK, NULL, NULL);
    expect("columns, good", strata_eval_batch_columns(b, 4, wi, wo, two, 1, f, se), STRATA_OK,
           NULL, NULL);

    /* ---- a good call clears the message */
    expect("good eval", strata_eval_batch(b, 4, wi, wo, f, se), STRATA_OK, NULL, NULL);

    /* ---- materials */
    StrataBsdf *m = (StrataBsdf *)&failures; /* must be reset to NULL on failure */
    expect("malformed TOML",
           strata_bsdf_from_toml("[[layers]]\ninterface = { kind = \"dielectric\", ior = \"x\" }\n",
                                 16, 0, &m),
           STRATA_ERR_MATERIAL, "invalid TOML material", "ior");
    checks++;
    if (m != NULL) {
        failures++;
        fprintf(stderr, "FAIL: *out is not NULL after a failed create\n");
    }
    expect("TOML syntax error", strata_bsdf_from_toml("[[layers]\n", 16, 0, &m),
           STRATA_ERR_MATERIAL, "invalid TOML material", NULL);
    expect("negative thickness",
           strata_bsdf_from_toml(
               "[[layers]]\n"
               "interface = { kind = \"dielectric\", ior = 1.5 }\n"
               "medium = { thickness = -0.5, sigma_t = 1.0, albedo = 0.5 }\n"
               "[[layers]]\n"
               "interface = { kind = \"diffuse\", albedo = 0.8 }\n",
               16, 0, &m),
           STRATA_ERR_MATERIAL, "layer 0: medium.thickness = -0.5", NULL);
    expect("malformed JSON", strata_bsdf_from_json("{\"layers\": [", 16, 0, &m),
           STRATA_ERR_MATERIAL, "invalid JSON material", NULL);
    expect("NULL text", strata_bsdf_from_toml(NULL, 16, 0, &m), STRATA_ERR_NULL,
           "toml is NULL", NULL);
    expect("NULL out", strata_bsdf_from_toml(GOOD, 16, 0, NULL), STRATA_ERR_NULL,
           "out is NULL", NULL);
    expect("0 samples", strata_bsdf_from_toml(GOOD, 0, 0, &m), STRATA_ERR_INVALID_ARGUMENT,
           "samples = 0", NULL);
    expect("missing file", strata_bsdf_from_path("/nonexistent/strata.toml", 16, 0, &m),
           STRATA_ERR_IO, "/nonexistent/strata.toml", NULL);
    expect("not UTF-8", strata_bsdf_from_toml("description = \"\xff\"\n", 16, 0, &m),
           STRATA_ERR_INVALID_ARGUMENT, "not UTF-8", NULL);

    strata_bsdf_free(b);
    printf("abuse: %d passed, %d failed\n", checks - failures, failures);
    return failures == 0 ? 0 : 1;
}
