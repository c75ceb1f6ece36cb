/*
 * leonav driver: the hand-written loop over the generated filter steps.
 *
 * Shared by the Python runtime (loaded with ctypes) and the standalone Pi program, so
 * it includes no Python header, never allocates inside a loop, never exits or aborts:
 * every function returns a status or an error code.
 *
 * Memory: the caller owns one workspace of leonav_work_size() bytes (8-byte aligned),
 * prepares it once with leonav_work_init() and passes it to every call. The workspace
 * holds pointers into itself, so it must not be moved after init. One workspace per
 * thread.
 *
 * Matrices: P, F, Qd, B are NDX x NDX, stored column-major (CasADi's order). P and B
 * are symmetric so the order does not matter for them; F does (F[i + j*NDX] = F_ij).
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

/* Record kind of an IMU sample; measurement kinds are the LEONAV_MEAS_* ids. */
#define LEONAV_KIND_IMU (-1)

/* Per-record status written by leonav_run (and returned by the step functions). */
#define LEONAV_STATUS_IMU (-1)     /* IMU record predicted */
#define LEONAV_STATUS_APPLIED 0    /* measurement applied */
#define LEONAV_STATUS_GATED 1      /* measurement rejected: nis above the gate */
#define LEONAV_STATUS_FAILED 2     /* numerical failure (S <= 0, non-finite input/result,
                                      R < 0, dt < 0): state and covariance left unchanged */

/* Error codes returned by the run / init functions (never a status). */
#define LEONAV_OK 0
#define LEONAV_ERR_WORK (-1)       /* workspace too small or not initialised */
#define LEONAV_ERR_KIND (-2)       /* record kind is neither IMU nor a LEONAV_MEAS_* id */
#define LEONAV_ERR_LAYOUT (-3)     /* a generated function's shape does not match state_layout.h */
#define LEONAV_ERR_ARG (-4)        /* a required pointer is NULL or n < 0 */
#define LEONAV_ERR_NUMERIC (-5)    /* PCRB: non-finite or non-positive innovation variance */

/* One record of a time-ordered stream. Mirrored by RECORD_DTYPE in records.py. */
typedef struct leonav_record {
    double t;                  /* s since the scenario epoch */
    int32_t kind;              /* LEONAV_KIND_IMU or LEONAV_MEAS_* */
    int32_t sat_id;            /* satellite id, -1 if none */
    double z;                  /* measurement, unit of its observable */
    double R;                  /* measurement noise variance, unit^2 */
    double dt;                 /* IMU interval, s (unused for measurements) */
    double u[6];               /* IMU increments: dtheta_b (rad, 3), dvel_b (m/s, 3), body FLU */
    double aux[LEONAV_NAUX];   /* satellite / reference / specific force block, see design.md */
} leonav_record;

/* Per-record outputs of leonav_run. Every array pointer may be NULL (not written). */
typedef struct leonav_run_out {
    double *x;        /* n * NX   state after the record */
    double *P_diag;   /* n * NDX  diagonal of P after the record */
    double *P;        /* full P after the record (column-major, NDX * NDX each): n blocks, or
                         one block per set flag of P_mask, packed in record order */
    const uint8_t *P_mask;  /* n flags or NULL (every record): which records write P */
    double *y;        /* n  innovation (NaN for IMU records and failures before it exists) */
    double *S;        /* n  innovation variance */
    double *nis;      /* n  normalised innovation squared y^2 / S */
    int32_t *status;  /* n  LEONAV_STATUS_* */
    long n_done;      /* records processed (== n unless an error code was returned) */
    long n_imu, n_applied, n_gated, n_failed;  /* counts; n_failed includes IMU failures */
} leonav_run_out;

/* Workspace size in bytes (maximum over every generated function's work sizes). */
size_t leonav_work_size(void);

/* Prepare a workspace of nbytes. Returns LEONAV_OK, LEONAV_ERR_WORK (too small, NULL)
 * or LEONAV_ERR_LAYOUT (a generated output is larger than NDX x NDX). */
int leonav_work_init(void *work, size_t nbytes);

/* Nominal mechanization over one interval, in place. Returns 0, or LEONAV_STATUS_FAILED
 * (x unchanged) on non-finite input or result. */
int leonav_mech_step(double *x, const double *u, double dt, const double *p, void *work);

/* Predict x (NX) and P in place over one IMU interval. F and Qd (NDX*NDX, column-major)
 * are written when not NULL. Returns LEONAV_STATUS_IMU, or LEONAV_STATUS_FAILED with x
 * and P unchanged (non-finite u/dt/result, dt < 0). */
/* dx[i] = x1[i] [-] x0[i] for i < n (rows of NX, results rows of NDX), with the generated
 * boxminus (attitude: body-frame rotation vector). Used to score estimates against truth. */
int leonav_boxminus_many(long n, const double *x1, const double *x0, double *dx, void *work);

int leonav_predict_step(double *x, double *P, const double *u, double dt, const double *p,
                        double *F, double *Qd, void *work);

/* Scalar update of observable `kind`, in place. gate_nis > 0 rejects nis > gate_nis;
 * gate_nis <= 0 disables gating. y_S_nis[3] (may be NULL) receives y, S, nis (NaN when
 * not computed). Returns LEONAV_STATUS_APPLIED / _GATED / _FAILED, or LEONAV_ERR_KIND. */
int leonav_update_step(double *x, double *P, int kind, double z, double R, const double *aux,
                       const double *p, double gate_nis, double *y_S_nis, void *work);

/* Prediction h and Jacobian H (1 x NDX, w.r.t. the error state) of observable `kind`.
 * Returns 0, LEONAV_ERR_KIND, or LEONAV_STATUS_FAILED on non-finite result. */
int leonav_h_step(int kind, const double *x, const double *aux, const double *p, double *h,
                  double *H, void *work);

/* Run the filter over n time-ordered records, updating x and P in place (final state).
 * gate_nis: LEONAV_NMEAS thresholds indexed by kind (<= 0 disables), or NULL for no
 * gating. Measurement failures are discarded and counted; the loop continues. An IMU
 * failure skips that predict (status 2) and the loop continues. Returns LEONAV_OK, or
 * LEONAV_ERR_KIND / _ERR_ARG / _ERR_WORK with out->n_done = index of the bad record. */
int leonav_run(double *x, double *P, const double *p, const leonav_record *rec, long n,
               const double *gate_nis, leonav_run_out *out, void *work);

/* Posterior Cramer-Rao bound B = J^-1 along a given trajectory, B updated in place.
 * x_lin (n * NX): state at which record i is linearised: for an IMU record the true
 * state at the start of its interval (t - dt), for a measurement the true state at t.
 * IMU: B <- F B F^T + Qd. Measurement: B <- B - B H^T H B / (H B H^T + R), H from
 * leonav_h_<kind> at x_lin. Outputs per record (each may be NULL): B_diag (n * NDX),
 * B_nav (n * 81, the 9x9 block of dp dv dtheta, column-major), B_full (n * NDX * NDX).
 * Returns LEONAV_OK, or an error code with *n_done = index of the failing record. */
int leonav_pcrb_run(double *B, const double *p, const leonav_record *rec, long n,
                    const double *x_lin, double *B_diag, double *B_nav, double *B_full,
                    long *n_done, void *work);

#ifdef __cplusplus
}
#endif

#endif /* LEONAV_DRIVER_H */
