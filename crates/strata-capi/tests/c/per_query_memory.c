/* Per-query columns have a memory bound (issue 39, item 2).
 *
 * 1. A batch of 10^6 queries on the coated copper whose rows all differ (a
 *    coat thickness column of 10^6 distinct values, 1 walk each) completes,
 *    and the process's peak RSS stays under 600 MB (it was about 4.1 GB when
 *    every row's material was held at once).
 * 2. Under a lowered address-space limit (RLIMIT_AS, in a child process) the
 *    same call returns STRATA_ERR_OUT_OF_MEMORY, with strata_last_error()
 *    naming the call and the bytes, instead of aborting.
 *
 * Exits 0 on success; prints what failed otherwise. */
#define _POSIX_C_SOURCE 200809L
#include "strata.h"

#include <math.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static const char *COATED_COPPER =
    "[[layers]]\n"
    "interface = { kind = \"dielectric\", ior = 1.5, roughness = 0.1 }\n"
    "medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }\n"
    "[[layers]]\n"
    "interface = { kind = \"conductor\", preset = \"Cu\", roughness = 0.2 }\n";

#define N 1000000
#define THICKNESS "layers[0].medium.thickness"
#define IOR "layers[0].interface.ior"
#define MAX_RSS_KB (600L * 1024L)

static float *wi, *wo, *f, *thickness;

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Queries of the warm call: many more one-walk queries than a batch runs on
 * the calling thread. */
#define WARM 4096

static int eval_columns(const struct StrataBsdf *b, size_t n, const char *path) {
    struct StrataColumn col = {path, 1, thickness};
    StrataBatch batch = {
        .n = n,
        .wi = {.xyz = wi},
        .wo = {.xyz = wo},
        .columns = &col,
        .ncolumns = 1,
        .f = {.xyz = f},
    };
    return strata_eval(b, &batch);
}

/* The address space the process has mapped now, in bytes. */
static long mapped_bytes(void) {
    FILE *s = fopen("/proc/self/statm", "r");
    long pages = -1;
    if (s == NULL) return -1;
    if (fscanf(s, "%ld", &pages) != 1) pages = -1;
    fclose(s);
    return pages < 0 ? -1 : pages * sysconf(_SC_PAGESIZE);
}

/* In a child: a warm call, large enough to go parallel, so that the pool's
 * threads and the buffers exist (glibc aborts a process that starts a
 * thread it cannot register under the limit), then the address space
 * limited to what is mapped, then the 10^6-row call: it must fail with
 * STRATA_ERR_OUT_OF_MEMORY, not abort. The column is the coat's IOR, whose
 * rows are materials (a thickness is written into the BSDF's numbers in
 * place, in a chunk's memory that the warm call already holds). */
static int out_of_memory_is_a_status(const struct StrataBsdf *b) {
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0) {
        perror("fork");
        return 1;
    }
    if (pid == 0) {
#ifdef __GLIBC__
        /* One malloc arena for every thread: glibc otherwise reserves 64 MB
         * of address space for a thread's first allocation, which the limit
         * refuses to a pool thread that sat out the warm call (an abort
         * outside strata's reach). */
        mallopt(M_ARENA_MAX, 1);
        /* Large blocks always from mmap: glibc otherwise raises the
         * threshold to the size of a large block the warm call freed, and
         * the limited call's working memory may then come from that freed
         * heap, so that the call goes on to build its rows and a later small
         * allocation fails instead (an abort: about one run in twenty). */
        mallopt(M_MMAP_THRESHOLD, 128 * 1024);
#endif
        if (eval_columns(b, WARM, IOR) != STRATA_OK) {
            fprintf(stderr, "warm call: %s\n", strata_last_error());
            _exit(2);
        }
        long mapped = mapped_bytes();
        if (mapped <= 0) _exit(3);
        struct rlimit lim = {(rlim_t)mapped, (rlim_t)mapped};
        if (setrlimit(RLIMIT_AS, &lim) != 0) {
            perror("setrlimit");
            _exit(4);
        }
        int status = eval_columns(b, N, IOR);
        const char *msg = strata_last_error();
        if (status != STRATA_ERR_OUT_OF_MEMORY) {
            fprintf(stderr, "limited call: status %d (%s)\n", status, msg);
            _exit(5);
        }
        if (strstr(msg, "strata_eval") == NULL ||
            strstr(msg, "out of memory") == NULL || strstr(msg, "bytes") == NULL) {
            fprintf(stderr, "limited call: message does not name the call: %s\n", msg);
            _exit(6);
        }
        printf("  limited to %ld MB of address space: status %d: %s\n", mapped >> 20,
               status, msg);
        fflush(stdout);
        _exit(0);
    }
    int ws = 0;
    if (waitpid(pid, &ws, 0) != pid) {
        perror("waitpid");
        return 1;
    }
    if (WIFSIGNALED(ws)) {
        fprintf(stderr, "the limited child died of signal %d\n", WTERMSIG(ws));
        return 1;
    }
    return WEXITSTATUS(ws) != 0;
}

int main(void) {
    wi = malloc(3 * sizeof(float) * N);
    wo = malloc(3 * sizeof(float) * N);
    f = malloc(3 * sizeof(float) * N);
    thickness = malloc(sizeof(float) * N);
    if (!wi || !wo || !f || !thickness) {
        fprintf(stderr, "malloc\n");
        return 1;
    }
    for (size_t k = 0; k < N; k++) {
        double t = 0.618034 * (double)k;
        float z = (float)(0.2 + 0.7 * fabs(sin(1.3 * t)));
        float r = sqrtf(1.0f - z * z);
        wi[3 * k] = r * (float)cos(t);
        wi[3 * k + 1] = r * (float)sin(t);
        wi[3 * k + 2] = z;
        wo[3 * k] = -wi[3 * k + 1];
        wo[3 * k + 1] = wi[3 * k];
        wo[3 * k + 2] = z;
        /* 10^6 distinct floats in [0.05, 1.05]. */
        thickness[k] = 0.05f + (float)k * 1e-6f;
    }
    struct StrataBsdf *b = NULL;
    if (strata_bsdf_from_toml(COATED_COPPER, 1, 7, &b) != STRATA_OK) {
        fprintf(stderr, "from_toml: %s\n", strata_last_error());
        return 1;
    }

    printf("out of memory under RLIMIT_AS (child):\n");
    if (out_of_memory_is_a_status(b)) return 1;

    double t0 = now();
    int status = eval_columns(b, N, THICKNESS);
    double dt = now() - t0;
    if (status != STRATA_OK) {
        fprintf(stderr, "10^6 distinct rows: status %d: %s\n", status, strata_last_error());
        return 1;
    }
    for (size_t k = 0; k < 3 * (size_t)N; k++) {
        if (!isfinite(f[k]) || f[k] < 0.0f) {
            fprintf(stderr, "f[%zu] = %g\n", k, (double)f[k]);
            return 1;
        }
    }
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    printf("10^6 queries, 10^6 distinct rows: %.1f s, peak RSS %ld MB (limit %ld MB)\n", dt,
           ru.ru_maxrss / 1024, MAX_RSS_KB / 1024);
    if (ru.ru_maxrss > MAX_RSS_KB) {
        fprintf(stderr, "peak RSS %ld KB is above %ld KB\n", ru.ru_maxrss, MAX_RSS_KB);
        return 1;
    }
    strata_bsdf_free(b);
    free(wi);
    free(wo);
    free(f);
    free(thickness);
    printf("per_query_memory: ok\n");
    return 0;
}
