/*
 * leonav_filter: the generated filter as a standalone program (no Python), for the Pi.
 *
 *   leonav_filter RECORDS.bin INIT.bin OUT.csv [GATE_NIS [COV_INTERVAL]]
 *
 * RECORDS.bin: a raw array of leonav_record (leonav_driver.h; NumPy: recs.tofile()).
 * INIT.bin:    x0 (NX), P0 (NDX*NDX, column-major; leonav_run symmetrizes it), p (NP) as little-endian doubles.
 * OUT.csv:     one row per record: t, kind, sat_id, status, y, S, nis, x[NX], P_diag[NDX].
 * GATE_NIS:    chi-square gate on every observable (default LEONAV_CHI2_1DOF_999 = 10.8276,
 *              the chi-square 1-dof 99.9 % quantile, as the Python EKF; 0 disables).
 * COV_INTERVAL: s, the covariance interval of leonav_run (default 0: P at every IMU record;
 *              > 0: P propagated once per run of IMU records that long, P_diag NaN inside).
 * status column: the per-record enum of leonav_run (-1 IMU, 0 applied, 1 gated, 2 failed).
 * Exit status: 0 ok, 2 bad arguments or files, 3 the run returned an error code (named on
 * stderr, LEONAV_ERR_*).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "constants.h"
#include "leonav_driver.h"

#define NMAT (LEONAV_NDX * LEONAV_NDX)

static void *read_all(const char *path, long *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    void *buf = NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (*size = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0) {
        buf = malloc(*size > 0 ? (size_t)*size : 1);
        if (buf && fread(buf, 1, (size_t)*size, f) != (size_t)*size) {
            free(buf);
            buf = NULL;
        }
    }
    fclose(f);
    return buf;
}

/* argv[i] as a finite number >= lo, or NAN after a message naming the argument. */
static double number_arg(const char *name, const char *text, double lo)
{
    char *end = NULL;
    double v = strtod(text, &end);
    if (end == text || *end != '\0' || !isfinite(v) || v < lo) {
        fprintf(stderr, "%s = '%s': expected a finite number >= %g\n", name, text, lo);
        return NAN;
    }
    return v;
}

int main(int argc, char **argv)
{
    if (argc < 4 || argc > 6) {
        fprintf(stderr, "usage: %s RECORDS.bin INIT.bin OUT.csv [GATE_NIS [COV_INTERVAL]]\n", argv[0]);
        return 2;
    }
    long rec_bytes = 0, init_bytes = 0;
    leonav_record *rec = read_all(argv[1], &rec_bytes);
    double *init = read_all(argv[2], &init_bytes);
    if (!rec || rec_bytes % (long)sizeof(leonav_record) != 0) {
        fprintf(stderr, "%s: not a whole number of %zu-byte records\n", argv[1], sizeof(leonav_record));
        return 2;
    }
    if (!init || init_bytes != (long)sizeof(double) * (LEONAV_NX + NMAT + LEONAV_NP)) {
        fprintf(stderr, "%s: expected %d doubles (x0, P0, p)\n", argv[2], LEONAV_NX + NMAT + LEONAV_NP);
        return 2;
    }
    long n = rec_bytes / (long)sizeof(leonav_record);
    double gate = argc >= 5 ? number_arg("GATE_NIS", argv[4], 0.0) : LEONAV_CHI2_1DOF_999;
    double cov_interval = argc == 6 ? number_arg("COV_INTERVAL", argv[5], 0.0) : 0.0;
    if (isnan(gate) || isnan(cov_interval)) return 2;
    double gates[LEONAV_NMEAS];
    for (int k = 0; k < LEONAV_NMEAS; ++k) gates[k] = gate;

    double *x = init, *P = init + LEONAV_NX, *p = init + LEONAV_NX + NMAT;
    double *xs = malloc(sizeof(double) * (size_t)(n * LEONAV_NX + 1));
    double *pd = malloc(sizeof(double) * (size_t)(n * LEONAV_NDX + 1));
    double *y = malloc(sizeof(double) * (size_t)(n + 1)), *S = malloc(sizeof(double) * (size_t)(n + 1));
    double *nis = malloc(sizeof(double) * (size_t)(n + 1));
    int32_t *status = malloc(sizeof(int32_t) * (size_t)(n + 1));
    size_t work_size = leonav_work_size();
    void *work = malloc(work_size);
    if (!xs || !pd || !y || !S || !nis || !status || !work || leonav_work_init(work, work_size) != LEONAV_OK) {
        fprintf(stderr, "out of memory or bad workspace\n");
        return 2;
    }
    leonav_run_out out = {xs, pd, NULL, NULL, y, S, nis, status, 0, 0, 0, 0, 0, 0};
    int rc = leonav_run(x, P, p, rec, n, gates, cov_interval, &out, work);

    FILE *f = fopen(argv[3], "w");
    if (!f) {
        fprintf(stderr, "%s: cannot write\n", argv[3]);
        return 2;
    }
    fprintf(f, "t,kind,sat_id,status,y,S,nis");
    for (int i = 0; i < LEONAV_NX; ++i) fprintf(f, ",x%d", i);
    for (int i = 0; i < LEONAV_NDX; ++i) fprintf(f, ",P%d", i);
    fprintf(f, "\n");
    for (long i = 0; i < out.n_done; ++i) {
        fprintf(f, "%.17g,%d,%d,%d,%.17g,%.17g,%.17g", rec[i].t, rec[i].kind, rec[i].sat_id, status[i], y[i], S[i],
                nis[i]);
        for (int j = 0; j < LEONAV_NX; ++j) fprintf(f, ",%.17g", xs[i * LEONAV_NX + j]);
        for (int j = 0; j < LEONAV_NDX; ++j) fprintf(f, ",%.17g", pd[i * LEONAV_NDX + j]);
        fprintf(f, "\n");
    }
    fclose(f);
    fprintf(stderr, "%ld records: %ld IMU, %ld applied, %ld gated, %ld failed\n", out.n_done, out.n_imu,
            out.n_applied, out.n_gated, out.n_failed);
    if (out.n_cv) fprintf(stderr, "  %ld constant-velocity predicts\n", out.n_cv);
    long applied[LEONAV_NMEAS] = {0};
    for (long i = 0; i < out.n_done; ++i)
        if (rec[i].kind >= 0 && rec[i].kind < LEONAV_NMEAS && status[i] == LEONAV_STATUS_APPLIED) applied[rec[i].kind]++;
    for (int k = 0; k < LEONAV_NMEAS; ++k)
        if (applied[k]) fprintf(stderr, "  %s (%s): %ld applied\n", leonav_meas_name(k), leonav_meas_unit(k), applied[k]);
    if (rc != LEONAV_OK) {
        fprintf(stderr, "leonav_run stopped at record %ld: %s (%d)\n", out.n_done, leonav_code_name(rc), rc);
        return 3;
    }
    return 0;
}
