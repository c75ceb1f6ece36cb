/*
 * leonav driver: the hand-written loop over the generated filter steps.
 *
 * Shared by the Python runtime (loaded with ctypes) and the standalone Pi program, so
 * it includes no Python header, never allocates inside a loop, never exits or aborts:
 * every function returns one of the codes below (LEONAV_OK on success).
 *
 * Memory: the caller owns one workspace of leonav_work_size() bytes (8-byte aligned),
 * prepares it once with leonav_work_init() and passes it to every call. The workspace
 * holds pointers into itself, so it must not be moved after init. One workspace per
 * thread.
 *
 * Matrices: P, F, Qd, B are NDX x NDX, stored column-major (CasADi's order). P and B
 * are symmetric so the order does not matter for them; F does (F[i + j*NDX] = F_ij). The
 * generated steps read the upper triangle of P (and of B in a predict) only, as LAPACK's
 * uplo = 'U', and write both triangles exactly symmetric; the single steps need a symmetric
 * P, the loops (leonav_run, leonav_run_orbit, leonav_pcrb_run) symmetrize theirs on entry.
 *
 * Time: a record's t is seconds since the scenario epoch. An IMU record at t carries
 * the increments integrated over (t - dt, t]; predicting with it brings the state to t.
 */
#ifndef LEONAV_DRIVER_H
#define LEONAV_DRIVER_H

#include <stddef.h>
#include <stdint.h>

#include "state_layout.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Codes (generated into state_layout.h from codegen/driver_codes.py, one definition for C and
 * Python; table in docs/design.md "C driver API"):
 *
 * Every function here that returns int returns one of
 *   LEONAV_OK (0)           success: the step was applied / the value computed
 *   LEONAV_GATED (1)        leonav_update_step only: nis above the gate, x and P unchanged
 *   LEONAV_FAILED (2)       numerical failure (non-finite input or result, R < 0, S <= 0,
 *                           dt < 0): x and P unchanged
 *   LEONAV_ERR_* (< 0)      an error of the call itself: _WORK (workspace NULL, too small or
 *                           not initialised), _KIND (kind neither LEONAV_MEAS_IMU nor a
 *                           LEONAV_MEAS_* id), _LAYOUT (generated shapes differ from
 *                           state_layout.h), _ARG (NULL pointer, n < 0), _NUMERIC (PCRB or
 *                           boxminus: a generated step failed, S is not positive and finite,
 *                           or R <= 0)
 * so `rc < 0` is always an error and `rc == LEONAV_OK` always success.
 *
 * leonav_run also writes a status per record (leonav_run_out.status), its own enum:
 *   LEONAV_STATUS_IMU (-1) IMU or CV record predicted, LEONAV_STATUS_APPLIED (0),
 *   LEONAV_STATUS_GATED (1), LEONAV_STATUS_FAILED (2) (IMU or measurement record).
 * A measurement record stores its update's return code; these values are never returned.
 *
 * Record kinds: LEONAV_MEAS_IMU (-1) for an IMU interval, LEONAV_KIND_CV (-2) for a
 * constant-velocity predict over dt (receivers without IMU), else a LEONAV_MEAS_* id; the
 * observables are listed by the generated X-macro LEONAV_MEAS_TABLE. */

/* One record of a time-ordered stream. Mirrored by RECORD_DTYPE in records.py. */
typedef struct leonav_record {
    double t;                  /* s since the scenario epoch */
    int32_t kind;              /* LEONAV_MEAS_IMU, LEONAV_KIND_CV or LEONAV_MEAS_* */
    int32_t sat_id;            /* satellite id, -1 if none */
    double z;                  /* measurement, unit of its observable */
    double R;                  /* measurement noise variance, unit^2 */
    double dt;                 /* IMU or CV interval, s (unused for measurements) */
    double u[LEONAV_NU];       /* IMU increments: dtheta_b (rad, 3), dvel_b (m/s, 3), body FLU */
    double aux[LEONAV_NAUX];   /* satellite / reference / specific force block, see design.md */
} leonav_record;

/* Per-record outputs of leonav_run. Every array pointer may be NULL (not written). */
typedef struct leonav_run_out {
    double *x;        /* n * NX   state after the record */
    double *P_diag;   /* n * NDX  diagonal of P after the record */
    double *P;        /* full P after the record (column-major, NDX * NDX each, or P_lead *
                         P_lead with P_lead below): n blocks, or one block per set flag of
                         P_mask, packed in record order */
    const uint8_t *P_mask;  /* n flags or NULL (every record): which records write P */
    double *y;        /* n  innovation (NaN for IMU records and failures before it exists) */
    double *S;        /* n  innovation variance */
    double *nis;      /* n  normalised innovation squared y^2 / S */
    int32_t *status;  /* n  LEONAV_STATUS_* (per-record enum above) */
    long n_done;      /* records processed (== n unless an error code was returned) */
    long n_imu, n_applied, n_gated, n_failed;  /* counts; n_failed includes IMU and CV failures */
    long n_cv;        /* constant-velocity predicts applied */
    long P_lead;      /* 0: each P block written is the full NDX x NDX; m in 1..NDX: only P's leading
                         m x m block (column-major, m * m doubles each), e.g. the 9D navigation
                         error's with LEONAV_NNAV, so a caller that needs no more reads no more */
} leonav_run_out;

/* Workspace size in bytes (maximum over every generated function's work sizes). */
size_t leonav_work_size(void);

/* Prepare a workspace of nbytes. Returns LEONAV_OK, LEONAV_ERR_WORK (too small, NULL)
 * or LEONAV_ERR_LAYOUT (a generated output is larger than NDX x NDX). */
int leonav_work_init(void *work, size_t nbytes);

/* Nominal mechanization over one interval, in place. Returns LEONAV_OK, LEONAV_FAILED
 * (x unchanged) on non-finite input or result, or LEONAV_ERR_WORK. */
int leonav_mech_step(double *x, const double *u, double dt, const double *p, void *work);

/* Predict x (NX) and P in place over one IMU interval. F and Qd (NDX*NDX, column-major)
 * are written when not NULL. Returns LEONAV_OK, LEONAV_FAILED with x and P unchanged
 * (non-finite u/dt/result, dt < 0), or LEONAV_ERR_WORK. */
int leonav_predict_step(double *x, double *P, const double *u, double dt, const double *p,
                        double *F, double *Qd, void *work);

/* Constant-velocity predict (record kind LEONAV_KIND_CV: a receiver without IMU) of x and P
 * in place over dt (generated leonav_predict_cv: p += v dt, c_dt += c_ddt dt, white
 * acceleration of PSD vrw^2). F, Qd written when not NULL. Returns LEONAV_OK, LEONAV_FAILED
 * (x, P unchanged: non-finite dt or result, dt < 0) or LEONAV_ERR_WORK. */
int leonav_predict_cv_step(double *x, double *P, double dt, const double *p, double *F, double *Qd, void *work);

/* dx[i] = x1[i] [-] x0[i] for i < n (rows of NX, results rows of NDX), with the generated
 * boxminus (attitude: body-frame rotation vector). Used to score estimates against truth.
 * Returns LEONAV_OK, LEONAV_ERR_WORK / _ARG / _NUMERIC. */
int leonav_boxminus_many(long n, const double *x1, const double *x0, double *dx, void *work);

/* Scalar update of observable `kind`, in place. gate_nis > 0 rejects nis > gate_nis;
 * gate_nis <= 0 disables gating. y_S_nis[3] (may be NULL) receives y, S, nis (NaN when
 * not computed). Returns LEONAV_OK (applied), LEONAV_GATED, LEONAV_FAILED (x, P unchanged
 * in both), LEONAV_ERR_WORK or LEONAV_ERR_KIND. */
int leonav_update_step(double *x, double *P, int kind, double z, double R, const double *aux,
                       const double *p, double gate_nis, double *y_S_nis, void *work);

/* Prediction h and Jacobian H (1 x NDX, w.r.t. the error state) of observable `kind`.
 * Returns LEONAV_OK, LEONAV_FAILED on a non-finite result, LEONAV_ERR_WORK or _KIND. */
int leonav_h_step(int kind, const double *x, const double *aux, const double *p, double *h,
                  double *H, void *work);

/* Batch of leonav_h_step for n rows: x (n * NX, one state per row), aux (n * NAUX), one p;
 * h (n), H (n * NDX, row i at H + i * NDX; may be NULL), status (n, may be NULL: each row's
 * leonav_h_step code). A failing row gets NaN in h and H. Returns LEONAV_OK, LEONAV_ERR_WORK,
 * _KIND or _ARG. */
int leonav_h_many(int kind, long n, const double *x, const double *aux, const double *p, double *h,
                  double *H, int32_t *status, void *work);

/* terms (n * 4) = [el (rad), az (rad), iono (m), tropo (m)] of the generated leonav_gnss_terms
 * for n rows (x n * NX, aux n * NAUX); NaN for a row whose result is not finite. Returns
 * LEONAV_OK, LEONAV_ERR_WORK or _ARG. */
int leonav_gnss_terms_many(long n, const double *x, const double *aux, const double *p, double *terms, void *work);

/* J (n * LEONAV_NORBIT, row i at J + i * NORBIT) = dh/d[r_S, v_S, r_ref, v_ref] (aux satellite
 * states, ECEF) of observable `kind` (one of LEONAV_ORBIT_JAC_TABLE) for n rows (x n * NX, aux
 * n * NAUX): the consider term of ephemeris error. NaN for a row whose result is not finite.
 * Returns LEONAV_OK, LEONAV_ERR_WORK, _KIND (no such Jacobian) or _ARG. */
int leonav_orbit_jacobian_many(int kind, long n, const double *x, const double *aux, const double *p, double *J,
                               void *work);

/* x_out[i] = x[i] [+] dx[i] for n rows (NX, NDX; x_out may be x). LEONAV_OK, _WORK, _ARG, _NUMERIC. */
int leonav_boxplus_many(long n, const double *x, const double *dx, double *x_out, void *work);

/* "LEONAV_OK", "LEONAV_ERR_KIND", ... for a return code (generated list); "LEONAV_?" if unknown. */
const char *leonav_code_name(int rc);

/* Name ("PSEUDORANGE", ...) and unit ("m", ...) of observable `kind` from the generated
 * LEONAV_MEAS_TABLE; NULL when kind is not a LEONAV_MEAS_* id. */
const char *leonav_meas_name(int kind);
const char *leonav_meas_unit(int kind);

/* M = (M + M^T) / 2 in place (NDX x NDX, column-major); an exactly symmetric M is unchanged. */
void leonav_symmetrize(double *M);

/* Write P (NDX x NDX, column-major) as the k-th P block of `out` (whole, or its leading
 * out->P_lead block; leonav_run_out). The run loops' own output, shared by the orbit-state loop. */
void leonav_output_P(const leonav_run_out *out, long k, const double *P);

/* Run the filter over n time-ordered records, updating x and P in place (final state); P is
 * symmetrized on entry (leonav_symmetrize).
 * gate_nis: LEONAV_NMEAS thresholds indexed by kind (<= 0 disables), or NULL for no
 * gating. Measurement failures are discarded and counted; the loop continues. An IMU
 * (or CV) failure skips that predict (status LEONAV_STATUS_FAILED) and the loop continues.
 * cov_interval (s, >= 0): 0 propagates P at every IMU record (leonav_predict). > 0
 * mechanizes x at every IMU record (leonav_mech) and propagates P once per run of IMU
 * records, with leonav_predict over their summed increments and intervals from the run's
 * first state. A run ends at the first record where its summed dt reaches cov_interval,
 * before any other record, at a record whose full P is an output and at the last record.
 * P_diag of a record inside a run is NaN (P is not formed there). A failed covariance step
 * fails its whole run: x goes back to the run's first state and P stays, and every record of
 * the run is a failed predict, as in the per-sample loop (status LEONAV_STATUS_FAILED, counted
 * in n_failed, its x the run's first state, its P_diag the P kept).
 * Returns LEONAV_OK, or LEONAV_ERR_KIND / _ERR_ARG (also cov_interval < 0 or not finite) /
 * _ERR_WORK with out->n_done = index of the bad record. */
int leonav_run(double *x, double *P, const double *p, const leonav_record *rec, long n,
               const double *gate_nis, double cov_interval, leonav_run_out *out, void *work);

/* Posterior Cramer-Rao bound B = J^-1 along a given trajectory, B updated in place.
 * x_lin (n * NX): state at which record i is linearised: for an IMU record the true
 * state at the start of its interval (t - dt), for a measurement the true state at t.
 * IMU: B <- F B F^T + Qd (leonav_predict); CV record: the same with leonav_predict_cv. Measurement: B <- B - B H^T H B / (H B H^T + R),
 * the generated leonav_pcrb_update with H of leonav_h_<kind> at x_lin (R must be > 0). Outputs per record
 * (each may be NULL): B_diag (n * NDX), B_nav (n * NNAV^2, the NNAV x NNAV block of dp dv
 * dtheta, column-major), B_full (n * NDX * NDX).
 * Returns LEONAV_OK, or an error code with *n_done = index of the failing record. */
int leonav_pcrb_run(double *B, const double *p, const leonav_record *rec, long n,
                    const double *x_lin, double *B_diag, double *B_nav, double *B_full,
                    long *n_done, void *work);

#ifdef __cplusplus
}
#endif

#endif /* LEONAV_DRIVER_H */
