/*
 * leonav orbit-offset states (ephemeris method 1): the generated filter with each tracked
 * satellite's radial, along-track and cross-track offset from its ephemeris (m) as three more
 * states. Built on the driver's public steps (leonav_driver.h): the generated predict, h and
 * boxplus; the augmented covariance algebra is here. C99, no allocation, no exit.
 *
 * The offsets of a satellite live in one of n_slots slots. A slot is taken by the satellite's
 * first applied record of an offset kind (its offsets start at 0 with the prior variances,
 * independent of everything else) and given to another satellite once its own has had no applied
 * record for free_after_s. Dropping the states is their marginal; a satellite seen again after
 * that starts from its prior, without what was learnt of it or its correlation with the
 * navigation state (an approximation, the price of a bounded state). An offset moves the satellite as
 * leonav_orbit_move_aux does; an offset kind's h is evaluated with its satellite moved by the
 * current estimate and differentiated by central differences of 1 m over the offsets.
 *
 * The covariance is [P (NDX x NDX, the caller's, as in leonav_run) | P_no; P_no^T | P_oo],
 * P_no NDX x 3 n_slots and P_oo 3 n_slots x 3 n_slots, column-major, slot j in columns 3j..3j+2;
 * of P_oo only the lower triangle (row >= column) is kept (the upper one is not written).
 * Per IMU record: the generated predict (P, F), P_no = F P_no, P_oo += q_rw dt on the taken
 * slots. Per measurement: one scalar Kalman update of the whole state in the Joseph form the
 * generated updates use (P - K c^T - c K^T, c = b - S K / 2).
 */
#ifndef LEONAV_ORBIT_STATES_H
#define LEONAV_ORBIT_STATES_H

#include "leonav_driver.h"

#ifdef __cplusplus
extern "C" {
#endif

#define LEONAV_ORBIT_MAX_SLOTS 256

typedef struct leonav_orbit_states {
    int32_t n_slots;                 /* 1..LEONAV_ORBIT_MAX_SLOTS */
    double prior_var[3];             /* m^2: radial, along, cross prior variance of a new satellite's offsets */
    double q_rw[3];                  /* m^2/s: random-walk PSD of the offsets (0: random constants) */
    double free_after_s;             /* s: a slot whose satellite had no record for this long can be reused */
    const uint8_t *kind_offsets;     /* LEONAV_NMEAS flags: kinds whose records read their satellite's offsets */
    int32_t *slot_sat;               /* n_slots: satellite id per slot, -1 free (set to -1 before a run) */
    double *slot_last_t;             /* n_slots: time of the slot satellite's last record (s) */
    double *offset;                  /* 3 n_slots: estimated radial, along, cross offsets (m) */
    double *P_no;                    /* NDX x 3 n_slots, column-major */
    double *P_oo;                    /* 3 n_slots x 3 n_slots, column-major, lower triangle */
    long n_taken, n_reused, n_no_slot;  /* slots taken, of them reused from a satellite gone, records without a slot */
} leonav_orbit_states;

/* aux (NAUX) with its satellite moved by offsets d (radial, along, cross; m) into aux_out (may
 * alias aux): the along-track offset as a time shift dt = d_A / (v . A) along the orbit
 * (r + v dt + a dt^2 / 2, v + a dt), radial and cross-track as offsets along the radial and
 * cross-track axes of (r, v); a time difference's start (aux dt_phase > 0) moves along the same
 * orbit, its velocity taken back over the interval with the end's acceleration. The same move as
 * the simulator's orbit truth (simulation/orbit_truth.move_aux). */
void leonav_orbit_move_aux(const double *aux, const double d[3], double *aux_out);

/* As leonav_run (the same outputs to rounding, P the navigation block), with the orbit-offset states of `orb`
 * carried beside it (their estimates, covariances and slots updated in place). Records of a kind
 * flagged in orb->kind_offsets need a satellite id >= 0; one that finds no slot is not applied
 * (status FAILED, counted in n_failed and orb->n_no_slot). Constant-velocity records are refused
 * (LEONAV_ERR_KIND at that record). Returns LEONAV_OK, or LEONAV_ERR_ARG (a NULL pointer, n_slots
 * outside 1..LEONAV_ORBIT_MAX_SLOTS), _ERR_KIND, _ERR_WORK with out->n_done = the bad record. */
int leonav_run_orbit(double *x, double *P, const double *p, const leonav_record *rec, long n,
                     const double *gate_nis, leonav_orbit_states *orb, leonav_run_out *out, void *work);

#ifdef __cplusplus
}
#endif

#endif /* LEONAV_ORBIT_STATES_H */
