/*
 * strata in a fork()ed child (issue 39): after batches large enough to run
 * on a thread pool (a BSDF's own, strata_bsdf_set_threads(b, 2), and the
 * default one), the same batches in a forked child, and in a child of that
 * child, return the parent's numbers bit for bit. Threads do not survive
 * fork: a child that entered the parent's pool would wait forever, so each
 * child is killed and counted a failure after 60 s. Exits 1 if any check
 * fails. Built and run by .ci/capi.sh.
 */
#define _POSIX_C_SOURCE 200809L

#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "strata.h"

#define N 4096       /* queries per batch */
#define WALKS 64     /* walks per eval */
#define TIMEOUT 60   /* seconds a child may take */
#define DEPTH 2      /* a child, and a child of the child */

static const char *MATERIAL =
    "[[layers]]\n"
    "interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n"
    "medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.8 }\n"
    "[[layers]]\n"
    "interface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.2 }\n";

static float wi[3 * N], wo[3 * N];

/* One BSDF's results: eval (values and errors), sample, pdf. */
struct Results {
    float f[3 * N], se[3 * N], pdf[N];
    StrataSample s[N];
};

static struct Results expected[2], got;

/* Fills `r` from the batches of `b`; 0 on success. */
static int run(const StrataBsdf *b, struct Results *r) {
    memset(r, 0, sizeof *r);
    StrataBatch eval = {
        .n = N, .wi = {.xyz = wi}, .wo = {.xyz = wo}, .f = {.xyz = r->f}, .stderr = {.xyz = r->se}};
    StrataBatch sample = {.n = N, .wi = {.xyz = wi}, .sample = r->s};
    StrataBatch pdf = {.n = N, .wi = {.xyz = wi}, .wo = {.xyz = wo}, .pdf = r->pdf};
    if (strata_eval(b, &eval) != STRATA_OK) return 1;
    if (strata_sample(b, &sample) != STRATA_OK) return 1;
    if (strata_pdf(b, &pdf) != STRATA_OK) return 1;
    return 0;
}

/* Whether `a` and `b` are the same bits. */
static int same(const struct Results *a, const struct Results *b) {
    return memcmp(a->f, b->f, sizeof a->f) == 0 && memcmp(a->se, b->se, sizeof a->se) == 0 &&
           memcmp(a->pdf, b->pdf, sizeof a->pdf) == 0 && memcmp(a->s, b->s, sizeof a->s) == 0;
}

/* In a child: the batches of both BSDFs again, then (above `depth` 1) the
 * same in a child of its own. Returns the exit status. */
static int child(StrataBsdf *const bsdfs[2], int depth);

/* Forks a child that runs `child(bsdfs, depth)` and waits for it at most
 * TIMEOUT seconds; 0 if it exited 0. */
static int in_child(StrataBsdf *const bsdfs[2], int depth) {
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        perror("fork");
        return 1;
    }
    if (pid == 0) _exit(child(bsdfs, depth));
    struct timespec tick = {0, 10 * 1000 * 1000};
    for (long waited = 0; waited < TIMEOUT * 100L; waited++) {
        int status = 0;
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid) {
            if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return 0;
            fprintf(stderr, "FAIL: child at depth %d: status %d\n", depth, status);
            return 1;
        }
        if (w < 0) {
            perror("waitpid");
            return 1;
        }
        nanosleep(&tick, NULL);
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    fprintf(stderr, "FAIL: child at depth %d still running after %d s: killed (a pool from "
                    "before fork?)\n",
            depth, TIMEOUT);
    return 1;
}

static int child(StrataBsdf *const bsdfs[2], int depth) {
    int failures = 0;
    for (int i = 0; i < 2; i++) {
        if (run(bsdfs[i], &got) != 0) {
            fprintf(stderr, "FAIL: depth %d, BSDF %d: %s\n", depth, i, strata_last_error());
            failures++;
        } else if (!same(&got, &expected[i])) {
            fprintf(stderr, "FAIL: depth %d, BSDF %d: results differ from the parent's\n",
                    depth, i);
            failures++;
        }
    }
    if (depth < DEPTH) failures += in_child(bsdfs, depth + 1);
    return failures == 0 ? 0 : 1;
}

int main(void) {
    for (int k = 0; k < N; k++) {
        float t = (float)k / N;
        wi[3 * k] = 0.7f * t - 0.35f;
        wi[3 * k + 1] = 0.2f * (float)(k % 7) / 7.0f;
        wi[3 * k + 2] = 1.0f;
        wo[3 * k] = -0.6f * t + 0.25f;
        wo[3 * k + 1] = 0.3f * (float)(k % 5) / 5.0f - 0.1f;
        wo[3 * k + 2] = (k % 3 == 0) ? -0.9f : 0.9f;
    }
    StrataBsdf *bsdfs[2] = {NULL, NULL};
    for (int i = 0; i < 2; i++) {
        if (strata_bsdf_from_toml(MATERIAL, WALKS, 7, &bsdfs[i]) != STRATA_OK) {
            fprintf(stderr, "FAIL: material: %s\n", strata_last_error());
            return 1;
        }
    }
    /* BSDF 0 on a pool of its own; BSDF 1 on the default threads. */
    if (strata_bsdf_set_threads(bsdfs[0], 2) != STRATA_OK) {
        fprintf(stderr, "FAIL: threads: %s\n", strata_last_error());
        return 1;
    }
    int failures = 0;
    for (int i = 0; i < 2; i++) {
        if (run(bsdfs[i], &expected[i]) != 0) {
            fprintf(stderr, "FAIL: parent, BSDF %d: %s\n", i, strata_last_error());
            return 1;
        }
    }
    if (!same(&expected[0], &expected[1])) {
        fprintf(stderr, "FAIL: 2 threads and the default threads differ\n");
        failures++;
    }
    failures += in_child(bsdfs, 1);
    /* And the parent's pools still work after the fork. */
    if (run(bsdfs[0], &got) != 0 || !same(&got, &expected[0])) {
        fprintf(stderr, "FAIL: parent after fork\n");
        failures++;
    }
    for (int i = 0; i < 2; i++) strata_bsdf_free(bsdfs[i]);
    if (failures != 0) {
        fprintf(stderr, "fork: %d failure(s)\n", failures);
        return 1;
    }
    printf("fork: ok (a child and a grandchild, %d queries x %d walks)\n", N, WALKS);
    return 0;
}
