/*
 * Benchmark only: the bare generated functions called from a minimal C loop (no driver,
 * no status, no outputs, no finiteness checks), as the floor for the driver's overhead.
 * Usage: bench_bare_loop RECORDS.bin INIT.bin REPEATS GATE
 *   RECORDS.bin: raw leonav_record array; INIT.bin: x0 (NX), P0 (NDX*NDX), p (NP) doubles.
 * Prints the best process CPU time over REPEATS runs of the whole stream and the final x.
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "leonav_driver.h"
#include "leonav_gen.h"

#define NMAT (LEONAV_NDX * LEONAV_NDX)
typedef int (*gen_fn)(const double **, double **, int *, double *, int);
typedef int (*work_fn)(int *, int *, int *, int *);

static void *read_file(const char *path, long *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *size = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *buf = malloc((size_t)*size);
    if (buf && fread(buf, 1, (size_t)*size, f) != (size_t)*size) { free(buf); buf = NULL; }
    fclose(f);
    return buf;
}

int main(int argc, char **argv)
{
    if (argc != 5) { fprintf(stderr, "usage: %s RECORDS.bin INIT.bin REPEATS GATE\n", argv[0]); return 2; }
    long rec_bytes = 0, init_bytes = 0;
    leonav_record *rec = read_file(argv[1], &rec_bytes);
    double *init = read_file(argv[2], &init_bytes);
    int repeats = atoi(argv[3]);
    double gate = atof(argv[4]);
    if (!rec || !init || init_bytes != (long)sizeof(double) * (LEONAV_NX + NMAT + LEONAV_NP)) {
        fprintf(stderr, "bad input files\n");
        return 2;
    }
    long n = rec_bytes / (long)sizeof(leonav_record);
    const double *x0 = init, *P0 = init + LEONAV_NX, *p = init + LEONAV_NX + NMAT;

    /* every observable's update, from the generated table (state_layout.h) */
#define UPDATE_FN(id, k, dim, name, unit) [id] = leonav_update_##k,
#define UPDATE_WORK(id, k, dim, name, unit) leonav_update_##k##_work,
    gen_fn update[LEONAV_NMEAS] = {LEONAV_MEAS_TABLE(UPDATE_FN)};
    work_fn works[] = {leonav_predict_work, LEONAV_MEAS_TABLE(UPDATE_WORK)};
    int sz_arg = 8, sz_res = 8, sz_iw = 0, sz_w = 0;
    for (size_t k = 0; k < sizeof works / sizeof works[0]; ++k) {
        int a, r, iw, w;
        works[k](&a, &r, &iw, &w);
        if (a > sz_arg) sz_arg = a;
        if (r > sz_res) sz_res = r;
        if (iw > sz_iw) sz_iw = iw;
        if (w > sz_w) sz_w = w;
    }
    const double **arg = malloc(sizeof(double *) * (size_t)sz_arg);
    double **res = malloc(sizeof(double *) * (size_t)sz_res);
    int *iw = malloc(sizeof(int) * (size_t)(sz_iw + 1));
    double *w = malloc(sizeof(double) * (size_t)(sz_w + 1));
    double x[LEONAV_NX], P[NMAT], xn[LEONAV_NX], Pn[NMAT], y, S, nis;

    double best = INFINITY;
    for (int rep = 0; rep < repeats; ++rep) {
        memcpy(x, x0, sizeof x);
        memcpy(P, P0, sizeof P);
        struct timespec t0, t1;
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t0);
        for (long i = 0; i < n; ++i) {
            const leonav_record *r = &rec[i];
            if (r->kind == LEONAV_MEAS_IMU) {
                arg[0] = x; arg[1] = P; arg[2] = r->u; arg[3] = &r->dt; arg[4] = p;
                res[0] = xn; res[1] = Pn; res[2] = NULL; res[3] = NULL;
                leonav_predict(arg, res, iw, w, 0);
                memcpy(x, xn, sizeof x);
                memcpy(P, Pn, sizeof P);
            } else {
                arg[0] = x; arg[1] = P; arg[2] = &r->z; arg[3] = &r->R; arg[4] = r->aux; arg[5] = p;
                res[0] = xn; res[1] = Pn; res[2] = &y; res[3] = &S; res[4] = &nis;
                update[r->kind](arg, res, iw, w, 0);
                if (S > 0.0 && !(gate > 0.0 && nis > gate)) {
                    memcpy(x, xn, sizeof x);
                    memcpy(P, Pn, sizeof P);
                }
            }
        }
        clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t1);
        double s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
        if (s < best) best = s;
    }
    printf("best_s %.9e\nrecords %ld\nx", best, n);
    for (int i = 0; i < LEONAV_NX; ++i) printf(" %.17g", x[i]);
    printf("\n");
    return 0;
}
