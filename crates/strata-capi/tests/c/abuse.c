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
    uint64_t truncated = 7;
    /* The descriptors of good calls; each check below changes one field. */
    const StrataBatch eval = {.n = 4, .wi = {.xyz = wi}, .wo = {.xyz = wo}, .f = {.xyz = f}};
    const StrataBatch sample = {.n = 4, .wi = {.xyz = wi}, .keys = keys, .sample = s};
    const StrataBatch pdfs = {.n = 4, .wi = {.xyz = wi}, .wo = {.xyz = wo}, .pdf = pdf};
    const StrataBatch albedo = {.n = 4, .wi = {.xyz = wi}, .walks = 8, .albedo = a};
    const StrataBatch empty = {0};
    StrataBatch d;

    /* ---- NULL BSDF, NULL descriptor */
    expect("eval, NULL b", strata_eval(NULL, &eval), STRATA_ERR_NULL, "b is NULL",
           "strata_eval");
    expect("sample, NULL b", strata_sample(NULL, &sample), STRATA_ERR_NULL, "b is NULL", NULL);
    expect("pdf, NULL b", strata_pdf(NULL, &pdfs), STRATA_ERR_NULL, "b is NULL", NULL);
    expect("albedo, NULL b", strata_albedo(NULL, &albedo), STRATA_ERR_NULL, "b is NULL", NULL);
    expect("eval, NULL batch", strata_eval(b, NULL), STRATA_ERR_NULL, "batch is NULL",
           "strata_eval");
    expect("sample, NULL batch", strata_sample(b, NULL), STRATA_ERR_NULL, "batch is NULL", NULL);
    expect("pdf, NULL batch", strata_pdf(b, NULL), STRATA_ERR_NULL, "batch is NULL", NULL);
    expect("pdf unbiased, NULL batch", strata_pdf_unbiased(b, NULL), STRATA_ERR_NULL,
           "batch is NULL", "strata_pdf_unbiased");
    expect("albedo, NULL batch", strata_albedo(b, NULL), STRATA_ERR_NULL, "batch is NULL", NULL);
    expect("transport, NULL b", strata_bsdf_set_transport(NULL, 0), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("estimator, NULL b", strata_bsdf_set_estimator(NULL, 0), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("pdf samples, NULL b", strata_bsdf_set_pdf_samples(NULL, 4), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("pdf walks, NULL b", strata_bsdf_set_pdf_walks(NULL, 8, 128, 0.1), STRATA_ERR_NULL,
           "b is NULL", NULL);
    expect("NULL b even with n = 0", strata_eval(NULL, &empty), STRATA_ERR_NULL, "b is NULL",
           NULL);
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

    /* ---- NULL arrays, n > 0: the message names the field and n */
    d = eval;
    d.wi.xyz = NULL;
    expect("eval, NULL wi", strata_eval(b, &d), STRATA_ERR_NULL, "wi is NULL (n = 4)", NULL);
    d = eval;
    d.wo.xyz = NULL;
    expect("eval, NULL wo", strata_eval(b, &d), STRATA_ERR_NULL, "wo is NULL (n = 4)", NULL);
    d = eval;
    d.f.xyz = NULL;
    expect("eval, NULL f", strata_eval(b, &d), STRATA_ERR_NULL, "f is NULL (n = 4)", NULL);
    d = sample;
    d.wi.xyz = NULL;
    expect("sample, NULL wi", strata_sample(b, &d), STRATA_ERR_NULL, "wi is NULL (n = 4)",
           "strata_sample");
    d = sample;
    d.sample = NULL;
    expect("sample, NULL out", strata_sample(b, &d), STRATA_ERR_NULL, "sample is NULL (n = 4)",
           NULL);
    d = pdfs;
    d.pdf = NULL;
    expect("pdf, NULL pdf", strata_pdf(b, &d), STRATA_ERR_NULL, "pdf is NULL (n = 4)", NULL);
    d = albedo;
    d.albedo = NULL;
    expect("albedo, NULL out", strata_albedo(b, &d), STRATA_ERR_NULL, "albedo is NULL (n = 4)",
           NULL);
    d = pdfs;
    d.walks = 8;
    expect("pdf unbiased, NULL pdf_stderr", strata_pdf_unbiased(b, &d), STRATA_ERR_NULL,
           "pdf_stderr is NULL (n = 4)", NULL);
    d = eval;
    d.wi = (StrataVectors){.x = wi, .z = wi};
    d.wo = (StrataVectors){.x = wo, .y = wo + 4, .z = wo + 8};
    d.f = (StrataVectorsOut){.x = f, .y = f + 4, .z = f + 8};
    expect("eval soa, NULL wi.y", strata_eval(b, &d), STRATA_ERR_NULL,
           "wi.y is NULL but wi.x is not (n = 4)", NULL);
    d.wi = (StrataVectors){.x = wi, .y = wi + 4, .z = wi + 8};
    d.stderr = (StrataVectorsOut){.x = se};
    expect("eval soa, one stderr array", strata_eval(b, &d), STRATA_ERR_NULL,
           "stderr.y is NULL", "pass all three or none");
    d = (StrataBatch){.n = 4,
                      .wi = {.x = wi, .y = wi + 4, .z = wi + 8},
                      .sampled = {.x = f, .y = f + 4, .z = f + 8},
                      .weight = {.x = se, .y = se + 4, .z = se + 8},
                      .pdf = pdf};
    expect("sample soa, NULL flags", strata_sample(b, &d), STRATA_ERR_NULL,
           "flags is NULL (n = 4)", NULL);

    /* ---- fields a call does not take, and one layout per field */
    d = pdfs;
    d.keys = keys;
    expect("pdf, keys", strata_pdf(b, &d), STRATA_ERR_INVALID_ARGUMENT, "keys is not NULL",
           "does not take it");
    d = sample;
    d.truncated = &truncated;
    expect("sample, truncated", strata_sample(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "truncated is not NULL", NULL);
    d = eval;
    d.walks = 16;
    expect("eval, walks", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT, "walks = 16",
           "takes no walk count");
    d = eval;
    d.wi.x = wi;
    expect("eval, both layouts", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "wi.xyz and wi.x, .y, .z are both set", NULL);
    uint32_t flags[4];
    d = sample;
    d.flags = flags;
    expect("sample, records and components", strata_sample(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "pass the records or the components", NULL);

    /* ---- n = 0 does nothing, whatever the arrays (but writes truncated) */
    expect("eval, n = 0", strata_eval(b, &empty), STRATA_OK, NULL, NULL);
    expect("sample, n = 0", strata_sample(b, &empty), STRATA_OK, NULL, NULL);
    expect("pdf, n = 0", strata_pdf(b, &empty), STRATA_OK, NULL, NULL);
    expect("pdf unbiased, n = 0", strata_pdf_unbiased(b, &empty), STRATA_OK, NULL, NULL);
    expect("albedo, n = 0", strata_albedo(b, &empty), STRATA_OK, NULL, NULL);
    d = empty;
    d.truncated = &truncated;
    expect("eval, n = 0, truncated", strata_eval(b, &d), STRATA_OK, NULL, NULL);
    checks++;
    if (truncated != 0) {
        failures++;
        fprintf(stderr, "FAIL: an empty eval left truncated = %llu\n",
                (unsigned long long)truncated);
    }

    /* ---- huge n: an error, not a crash */
    d = eval;
    d.n = SIZE_MAX;
    d.wi.xyz = NULL;
    expect("eval, huge n, NULL", strata_eval(b, &d), STRATA_ERR_NULL, "wi is NULL", NULL);
    d = eval;
    d.n = SIZE_MAX / 2;
    expect("eval, huge n", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT, "too large", NULL);

    /* ---- bad directions: the message names the query and the argument */
    float bad[12];
    memcpy(bad, wi, sizeof bad);
    bad[6] = NAN; /* query 2, wi.x */
    for (int i = 0; i < 12; i++) f[i] = -7.0f;
    d = eval;
    d.wi.xyz = bad;
    d.truncated = &truncated;
    truncated = 7;
    expect("eval, NaN wi", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "query 2: wi = [NaN", "must be finite");
    int untouched = 1;
    for (int i = 0; i < 12; i++) untouched &= f[i] == -7.0f;
    checks++;
    if (!untouched || truncated != 7) {
        failures++;
        fprintf(stderr, "FAIL: a failed eval wrote to f or truncated\n");
    }
    d = sample;
    d.wi.xyz = bad;
    d.keys = NULL;
    expect("sample, NaN wi", strata_sample(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "query 2: wi = [NaN", NULL);
    d = albedo;
    d.wi.xyz = bad;
    expect("albedo, NaN wi", strata_albedo(b, &d), STRATA_ERR_INVALID_ARGUMENT, "query 2: wi",
           NULL);
    memcpy(bad, wo, sizeof bad);
    bad[3] = bad[4] = bad[5] = 0.0f; /* query 1, wo = 0 */
    d = eval;
    d.wo.xyz = bad;
    d.stderr.xyz = se;
    expect("eval, zero wo", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "query 1: wo = [0, 0, 0]", "zero length");
    d = pdfs;
    d.wo.xyz = bad;
    expect("pdf, zero wo", strata_pdf(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "query 1: wo = [0, 0, 0]", NULL);
    bad[3] = INFINITY;
    d = eval;
    d.wo.xyz = bad;
    d.keys = keys;
    expect("eval keyed, infinite wo", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "query 1: wo = [inf", NULL);

    /* ---- other bad arguments */
    d = albedo;
    d.walks = 0;
    expect("albedo, 0 walks", strata_albedo(b, &d), STRATA_ERR_INVALID_ARGUMENT, "walks = 0",
           NULL);
    expect("transport 7", strata_bsdf_set_transport(b, 7), STRATA_ERR_INVALID_ARGUMENT,
           "mode = 7", NULL);
    expect("estimator 3", strata_bsdf_set_estimator(b, 3), STRATA_ERR_INVALID_ARGUMENT,
           "estimator = 3", NULL);
    expect("pdf walks, pilot 1", strata_bsdf_set_pdf_walks(b, 1, 64, 0.1),
           STRATA_ERR_INVALID_ARGUMENT, "pilot = 1", NULL);
    expect("pdf walks, NaN error", strata_bsdf_set_pdf_walks(b, 8, 64, NAN),
           STRATA_ERR_INVALID_ARGUMENT, "rel_stderr = NaN", NULL);
    d = eval;
    d.f.xyz = wi;
    expect("overlapping arrays", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "wi.xyz and f.xyz overlap", NULL);
    char raw[64];
    d = eval;
    d.n = 1;
    d.wi.xyz = (const float *)(raw + 1);
    expect("misaligned wi", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT, "not aligned",
           NULL);

    /* ---- per-query columns: the message names the column or query, the
     * path and the value; nothing is written */
    const float thick[4] = {0.1f, 0.2f, -0.5f, 0.4f}; /* query 2 is invalid */
    const float good_thick[4] = {0.1f, 0.2f, 0.3f, 0.4f};
    StrataColumn col = {"layers[0].medium.thickness", 1, good_thick};
    d = eval;
    d.ncolumns = 1;
    expect("columns, NULL array", strata_eval(b, &d), STRATA_ERR_NULL,
           "columns is NULL (ncolumns = 1)", "strata_eval");
    col.path = NULL;
    d.columns = &col;
    expect("columns, NULL path", strata_eval(b, &d), STRATA_ERR_NULL, "columns[0].path is NULL",
           NULL);
    col.path = "layers[0].medium.thickness";
    col.values = NULL;
    d = sample;
    d.keys = NULL;
    d.columns = &col;
    d.ncolumns = 1;
    expect("columns, NULL values", strata_sample(b, &d), STRATA_ERR_NULL,
           "columns[0].values is NULL (n = 4)", "strata_sample");
    col.values = good_thick;
    col.width = 2;
    d = pdfs;
    d.columns = &col;
    d.ncolumns = 1;
    expect("columns, width 2", strata_pdf(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "columns[0].width = 2", "layers[0].medium.thickness");
    col.width = 1;
    col.path = "layers[0].medium.kind";
    d = albedo;
    d.columns = &col;
    d.ncolumns = 1;
    expect("columns, not a settable path", strata_albedo(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "columns[0]", "layers[0].medium.kind");
    col.path = "layers[0].medium.thick\xffness";
    d = eval;
    d.columns = &col;
    d.ncolumns = 1;
    expect("columns, path not UTF-8", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "columns[0].path is not UTF-8", NULL);
    col.path = "layers[0].medium.thickness";
    col.values = thick;
    for (int i = 0; i < 12; i++) f[i] = -7.0f;
    d.stderr.xyz = se;
    expect("columns, negative thickness at query 2", strata_eval(b, &d), STRATA_ERR_MATERIAL,
           "query 2: set `layers[0].medium.thickness` = -0.5",
           "layer 0: medium.thickness = -0.5");
    untouched = 1;
    for (int i = 0; i < 12; i++) untouched &= f[i] == -7.0f;
    checks++;
    if (!untouched) {
        failures++;
        fprintf(stderr, "FAIL: a failed eval with columns wrote to f\n");
    }
    const float nan_sigma[12] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, NAN, 1}; /* query 3 */
    StrataColumn two[2] = {{"layers[0].medium.thickness", 1, good_thick},
                           {"layers[0].medium.sigma_t", 3, nan_sigma}};
    d = pdfs;
    d.walks = 8;
    d.pdf_stderr = se;
    d.columns = two;
    d.ncolumns = 2;
    expect("columns, NaN sigma_t at query 3", strata_pdf_unbiased(b, &d),
           STRATA_ERR_INVALID_ARGUMENT, "query 3: set `layers[0].medium.sigma_t` = NaN",
           "not a finite number");
    for (int i = 0; i < 12; i++) f[i] = 0.3f;
    StrataColumn in_f = {"layers[0].medium.thickness", 1, f}; /* f is also an output */
    d = eval;
    d.keys = keys;
    d.columns = &in_f;
    d.ncolumns = 1;
    expect("columns, overlapping an output", strata_eval(b, &d), STRATA_ERR_INVALID_ARGUMENT,
           "f.xyz and columns[0].values overlap", NULL);
    d = empty;
    d.ncolumns = 3;
    expect("columns, n = 0", strata_eval(b, &d), STRATA_OK, NULL, NULL);
    d = eval;
    d.stderr.xyz = se;
    d.columns = two;
    d.ncolumns = 1;
    expect("columns, good", strata_eval(b, &d), STRATA_OK, NULL, NULL);

    /* ---- a good call clears the message, and counts no truncated walk */
    d = eval;
    d.stderr.xyz = se;
    d.truncated = &truncated;
    truncated = 7;
    expect("good eval", strata_eval(b, &d), STRATA_OK, NULL, NULL);
    checks++;
    if (truncated != 0) {
        failures++;
        fprintf(stderr, "FAIL: a good eval left truncated = %llu\n",
                (unsigned long long)truncated);
    }

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

    /* ---- settings as text */
    size_t needed = 0;
    expect("config size", strata_bsdf_config(b, NULL, 0, &needed), STRATA_OK, NULL, NULL);
    char text[512], small[8] = "xxxxxxx";
    checks++;
    if (needed < 2 || needed > sizeof text) {
        failures++;
        fprintf(stderr, "FAIL: config needs %zu bytes\n", needed);
        needed = sizeof text;
    }
    expect("config", strata_bsdf_config(b, text, sizeof text, NULL), STRATA_OK, NULL, NULL);
    checks++;
    if (strlen(text) + 1 != needed || strstr(text, "samples=16 ") != text) {
        failures++;
        fprintf(stderr, "FAIL: config printed \"%s\" (%zu bytes)\n", text, needed);
    }
    expect("config too small", strata_bsdf_config(b, small, sizeof small, NULL),
           STRATA_ERR_INVALID_ARGUMENT, "len = 8 is too small", NULL);
    checks++;
    if (small[0] != '\0' || small[1] != 'x') {
        failures++;
        fprintf(stderr, "FAIL: a buffer too small is not the empty string\n");
    }
    expect("config NULL buf", strata_bsdf_config(b, NULL, 8, NULL), STRATA_ERR_NULL,
           "buf is NULL", NULL);
    expect("configure", strata_bsdf_configure(b, "seed=3 transport=radiance"), STRATA_OK,
           NULL, NULL);
    expect("configure bad value", strata_bsdf_configure(b, "seed=4 rr_threshold=2"),
           STRATA_ERR_INVALID_ARGUMENT, "strata_bsdf_configure: rr_threshold=2: ", NULL);
    expect("configure unknown key", strata_bsdf_configure(b, "colour=red"),
           STRATA_ERR_INVALID_ARGUMENT, "colour=red: unknown setting", NULL);
    expect("configure not UTF-8", strata_bsdf_configure(b, "seed=\xff"),
           STRATA_ERR_INVALID_ARGUMENT, "settings is not UTF-8", NULL);
    expect("configure NULL", strata_bsdf_configure(b, NULL), STRATA_ERR_NULL,
           "settings is NULL", NULL);
    expect("configure NULL b", strata_bsdf_configure(NULL, "seed=1"), STRATA_ERR_NULL,
           "b is NULL", NULL);
    char after[512];
    expect("config after", strata_bsdf_config(b, after, sizeof after, NULL), STRATA_OK, NULL,
           NULL);
    checks++;
    if (strcmp(after, text) != 0) {
        failures++;
        fprintf(stderr, "FAIL: failed configures changed \"%s\" to \"%s\"\n", text, after);
    }

    strata_bsdf_free(b);
    printf("abuse: %d passed, %d failed\n", checks - failures, failures);
    return failures == 0 ? 0 : 1;
}
