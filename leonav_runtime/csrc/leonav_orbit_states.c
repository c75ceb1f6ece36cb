/*
 * leonav orbit-offset states (ephemeris method 1). See leonav_orbit_states.h for the contract.
 */
#include "leonav_orbit_states.h"

#include <math.h>
#include <string.h>

#include "leonav_gen.h"

#define NX LEONAV_NX
#define NDX LEONAV_NDX
#define NMAT (LEONAV_NDX * LEONAV_NDX)
#define STEP_M 1.0   /* central-difference step of the offsets (m): h is smooth over km */

/* ---- the move of a satellite by its offsets ------------------------------------- */

static void cross3(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double norm3(const double *a) { return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

/* (r, v, a) moved by d (radial, along, cross) into (r_out, v_out) */
static void perturb(const double *r, const double *v, const double *a, const double *d, double *r_out,
                    double *v_out)
{
    double R[3], C[3], A[3];
    const double nr = norm3(r);
    for (int i = 0; i < 3; ++i) R[i] = r[i] / nr;
    cross3(r, v, C);
    const double nc = norm3(C);
    for (int i = 0; i < 3; ++i) C[i] /= nc;
    cross3(C, R, A);
    const double dt = d[1] / (v[0] * A[0] + v[1] * A[1] + v[2] * A[2]);
    for (int i = 0; i < 3; ++i) {
        r_out[i] = r[i] + v[i] * dt + 0.5 * a[i] * dt * dt + d[0] * R[i] + d[2] * C[i];
        v_out[i] = v[i] + a[i] * dt;
    }
}

void leonav_orbit_move_aux(const double *aux, const double d[3], double *aux_out)
{
    double r[3], v[3], a[3], r1[3], v1[3];
    memcpy(r, aux + LEONAV_AUX_R_S_ECEF, sizeof r);
    memcpy(v, aux + LEONAV_AUX_V_S_ECEF, sizeof v);
    memcpy(a, aux + LEONAV_AUX_A_S_ECEF, sizeof a);
    const double T = aux[LEONAV_AUX_DT_PHASE];
    if (aux_out != aux) memcpy(aux_out, aux, sizeof(double) * LEONAV_NAUX);
    perturb(r, v, a, d, r1, v1);
    memcpy(aux_out + LEONAV_AUX_R_S_ECEF, r1, sizeof r1);
    memcpy(aux_out + LEONAV_AUX_V_S_ECEF, v1, sizeof v1);
    if (T > 0.0) {   /* the start of a time difference, on the same orbit */
        double r0[3], v0[3], r0m[3], v0m[3];
        memcpy(r0, aux + LEONAV_AUX_R_S_PREV_ECEF, sizeof r0);
        for (int i = 0; i < 3; ++i) v0[i] = v[i] - a[i] * T;
        perturb(r0, v0, a, d, r0m, v0m);
        memcpy(aux_out + LEONAV_AUX_R_S_PREV_ECEF, r0m, sizeof r0m);
    }
}

/* ---- slots ---------------------------------------------------------------------- */

static int finite_all(const double *v, int n)
{
    for (int i = 0; i < n; ++i)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* Pointers set, n_slots in range, and the slots in use a prefix 0..n-1 (what `slots_in_use` and
 * the loops over it rely on; a caller's -1 between taken slots is refused). */
static int valid(const leonav_orbit_states *o)
{
    if (!(o && o->n_slots >= 1 && o->n_slots <= LEONAV_ORBIT_MAX_SLOTS && o->kind_offsets && o->slot_sat &&
          o->slot_last_t && o->offset && o->P_no && o->P_oo))
        return 0;
    int seen_free = 0;
    for (int j = 0; j < o->n_slots; ++j) {
        if (o->slot_sat[j] < 0) seen_free = 1;
        else if (seen_free) return 0;
    }
    return 1;
}

/* Forget slot j (its rows and columns) and give it to satellite `sat` with the prior. */
static void take_slot(leonav_orbit_states *o, int j, int32_t sat, double t)
{
    const int m = 3 * o->n_slots;
    for (int c = 3 * j; c < 3 * j + 3; ++c) {
        memset(o->P_no + (size_t)c * NDX, 0, sizeof(double) * NDX);
        for (int r = 0; r < m; ++r) o->P_oo[r + (size_t)c * m] = o->P_oo[c + (size_t)r * m] = 0.0;
        o->P_oo[c + (size_t)c * m] = o->prior_var[c - 3 * j];
        o->offset[c] = 0.0;
    }
    o->slot_sat[j] = sat;
    o->slot_last_t[j] = t;
}

/* A slot's contents, kept while a new satellite tries it: a record that is then not applied
 * gives the slot back as it was (nothing changes unless an update is applied). */
typedef struct {
    int j;
    int32_t sat;
    double last_t, offset[3], P_no[3 * NDX], P_oo_col[3 * 3 * LEONAV_ORBIT_MAX_SLOTS],
        P_oo_row[3 * 3 * LEONAV_ORBIT_MAX_SLOTS];
} slot_copy;

static void keep_slot(const leonav_orbit_states *o, int j, slot_copy *k)
{
    const int m = 3 * o->n_slots;
    k->j = j;
    k->sat = o->slot_sat[j];
    k->last_t = o->slot_last_t[j];
    memcpy(k->offset, o->offset + 3 * j, sizeof k->offset);
    memcpy(k->P_no, o->P_no + (size_t)(3 * j) * NDX, sizeof k->P_no);
    for (int a = 0; a < 3; ++a)
        for (int r = 0; r < m; ++r) {
            k->P_oo_col[a * m + r] = o->P_oo[r + (size_t)(3 * j + a) * m];
            k->P_oo_row[a * m + r] = o->P_oo[(3 * j + a) + (size_t)r * m];
        }
}

static void give_back(leonav_orbit_states *o, const slot_copy *k)
{
    const int m = 3 * o->n_slots, j = k->j;
    o->slot_sat[j] = k->sat;
    o->slot_last_t[j] = k->last_t;
    memcpy(o->offset + 3 * j, k->offset, sizeof k->offset);
    memcpy(o->P_no + (size_t)(3 * j) * NDX, k->P_no, sizeof k->P_no);
    for (int a = 0; a < 3; ++a)
        for (int r = 0; r < m; ++r) {
            o->P_oo[r + (size_t)(3 * j + a) * m] = k->P_oo_col[a * m + r];
            o->P_oo[(3 * j + a) + (size_t)r * m] = k->P_oo_row[a * m + r];
        }
}

/* The slot satellite `sat` holds, or -1. */
static int held_slot(const leonav_orbit_states *o, int32_t sat)
{
    for (int j = 0; j < o->n_slots; ++j)
        if (o->slot_sat[j] == sat) return j;
    return -1;
}

/* The slot a new satellite would take at time t: the lowest free one, else the longest idle one
 * whose satellite had no applied record for free_after_s; -1 when every slot is held. */
static int free_slot(const leonav_orbit_states *o, double t, int *reused)
{
    int idle_j = -1;
    for (int j = 0; j < o->n_slots; ++j) {
        if (o->slot_sat[j] < 0) {
            *reused = 0;
            return j;
        }
        if (t - o->slot_last_t[j] > o->free_after_s && (idle_j < 0 || o->slot_last_t[j] < o->slot_last_t[idle_j]))
            idle_j = j;
    }
    *reused = idle_j >= 0;
    return idle_j;
}

/* ---- predict and update of the augmented state ----------------------------------- */

/* Slots are taken lowest free first, and a free slot a record tried without being applied goes
 * back to free (it was the lowest free one), so the slots in use are 0..n-1 (`valid` checks a
 * caller's table): the loops below run over them without a test per slot (a free slot holds
 * zeros, and its gain is zero). */
static int slots_in_use(const leonav_orbit_states *o)
{
    int n = 0;
    while (n < o->n_slots && o->slot_sat[n] >= 0) ++n;
    return n;
}

static int predict(double *x, double *P, const leonav_record *r, const double *p, leonav_orbit_states *o,
                   void *work)
{
    double F[NMAT], Qd[NMAT], col[NDX];
    int rc = leonav_predict_step(x, P, r->u, r->dt, p, F, Qd, work);
    if (rc != LEONAV_OK) return rc;
    /* P_no = F P_no over F's non-zeros (the error-state transition is sparse) */
    int nz_i[NMAT], nz_k[NMAT], nnz = 0;
    double nz_v[NMAT];
    for (int k = 0; k < NDX; ++k)
        for (int i = 0; i < NDX; ++i)
            if (F[i + k * NDX] != 0.0) {
                nz_i[nnz] = i;
                nz_k[nnz] = k;
                nz_v[nnz++] = F[i + k * NDX];
            }
    const int m = 3 * o->n_slots, used = slots_in_use(o);
    for (int j = 0; j < used; ++j) {
        for (int c = 3 * j; c < 3 * j + 3; ++c) {
            double *pc = o->P_no + (size_t)c * NDX;
            memset(col, 0, sizeof col);
            for (int e = 0; e < nnz; ++e) col[nz_i[e]] += nz_v[e] * pc[nz_k[e]];
            memcpy(pc, col, sizeof col);
            o->P_oo[c + (size_t)c * m] += o->q_rw[c - 3 * j] * r->dt;
        }
    }
    return LEONAV_OK;
}

/* h and H_nav of record r with its satellite moved by the slot's estimate, and H_orb (3) */
static int model(const double *x, const leonav_record *r, const double *p, const double *d, double *h,
                 double *H, double *H_orb, void *work)
{
    double aux[LEONAV_NAUX], hp, hm, dd[3];
    leonav_orbit_move_aux(r->aux, d, aux);
    int rc = leonav_h_step(r->kind, x, aux, p, h, H, work);
    if (rc != LEONAV_OK) return rc;
    for (int a = 0; a < 3; ++a) {
        memcpy(dd, d, sizeof dd);
        dd[a] = d[a] + STEP_M;
        leonav_orbit_move_aux(r->aux, dd, aux);
        rc = leonav_h_step(r->kind, x, aux, p, &hp, NULL, work);
        if (rc != LEONAV_OK) return rc;
        dd[a] = d[a] - STEP_M;
        leonav_orbit_move_aux(r->aux, dd, aux);
        rc = leonav_h_step(r->kind, x, aux, p, &hm, NULL, work);
        if (rc != LEONAV_OK) return rc;
        H_orb[a] = (hp - hm) / (2.0 * STEP_M);
    }
    return LEONAV_OK;
}

static int apply(double *x, double *P, const leonav_record *r, double h, const double *H, int j, const double *Ho,
                 double gate, leonav_orbit_states *o, double *ysn, void *work);

/* Scalar update; returns LEONAV_OK, _GATED or _FAILED: nothing changes unless OK (a new
 * satellite's slot included: it is taken only by an applied record). */
static int update(double *x, double *P, const leonav_record *r, const double *p, double gate,
                  leonav_orbit_states *o, double *ysn, void *work)
{
    double h, H[NDX], Ho[3] = {0.0, 0.0, 0.0};
    ysn[0] = ysn[1] = ysn[2] = NAN;
    if (!isfinite(r->z) || !isfinite(r->R) || r->R < 0.0) return LEONAV_FAILED;
    if (!finite_all(r->aux, LEONAV_NAUX)) return LEONAV_FAILED;
    int j = -1, rc, reused = 0;
    slot_copy kept;   /* a new satellite's slot as it was (37 kB at most; not static: threads may share the library) */
    int trying = 0;
    if (o->kind_offsets[r->kind]) {
        j = r->sat_id >= 0 ? held_slot(o, r->sat_id) : -1;
        if (j < 0 && r->sat_id >= 0) {
            j = free_slot(o, r->t, &reused);
            if (j >= 0) {
                keep_slot(o, j, &kept);
                take_slot(o, j, r->sat_id, r->t);
                trying = 1;
            }
        }
        if (j < 0) {
            o->n_no_slot++;
            return LEONAV_FAILED;
        }
        rc = model(x, r, p, o->offset + 3 * j, &h, H, Ho, work);
    } else {
        rc = leonav_h_step(r->kind, x, r->aux, p, &h, H, work);
    }
    int step = rc == LEONAV_OK ? apply(x, P, r, h, H, j, Ho, gate, o, ysn, work) : LEONAV_FAILED;
    if (step == LEONAV_OK && j >= 0) {
        o->slot_last_t[j] = r->t;
        if (trying) {
            o->n_taken++;
            o->n_reused += reused;
        }
    } else if (trying) {
        give_back(o, &kept);
    }
    return step;
}

/* The update of record r with h, H (nav) and Ho (slot j, -1 for none) evaluated. */
static int apply(double *x, double *P, const leonav_record *r, double h, const double *H, int j, const double *Ho,
                 double gate, leonav_orbit_states *o, double *ysn, void *work)
{
    const int m = 3 * o->n_slots;
    double bn[NDX], bo[3 * LEONAV_ORBIT_MAX_SLOTS];
    const double y = r->z - h;
    /* b = P_aug H^T, H = [H | Ho at slot j] */
    for (int i = 0; i < NDX; ++i) {
        double s = 0.0;
        for (int k = 0; k < NDX; ++k) s += P[i + k * NDX] * H[k];
        if (j >= 0)
            for (int a = 0; a < 3; ++a) s += o->P_no[i + (size_t)(3 * j + a) * NDX] * Ho[a];
        bn[i] = s;
    }
    const int mu = 3 * slots_in_use(o);   /* the columns in use (j < mu / 3) */
    for (int c = 0; c < mu; ++c) {
        double s = 0.0;
        const double *pc = o->P_no + (size_t)c * NDX;
        for (int k = 0; k < NDX; ++k) s += pc[k] * H[k];
        if (j >= 0)
            for (int a = 0; a < 3; ++a) {   /* P_oo holds its lower triangle (row >= column) */
                const int k = 3 * j + a;
                s += (c >= k ? o->P_oo[c + (size_t)k * m] : o->P_oo[k + (size_t)c * m]) * Ho[a];
            }
        bo[c] = s;
    }
    double S = r->R;
    for (int k = 0; k < NDX; ++k) S += H[k] * bn[k];
    if (j >= 0)
        for (int a = 0; a < 3; ++a) S += Ho[a] * bo[3 * j + a];
    ysn[0] = y;
    ysn[1] = S;
    ysn[2] = y * y / S;
    if (!(S > 0.0) || !isfinite(S) || !isfinite(ysn[2]) || !finite_all(bn, NDX) || !finite_all(bo, mu))
        return LEONAV_FAILED;
    if (gate > 0.0 && ysn[2] > gate) return LEONAV_GATED;
    /* K = b / S, c = b - S K / 2; P_aug -= K c^T + c K^T */
    double Kn[NDX], cn[NDX], Ko[3 * LEONAV_ORBIT_MAX_SLOTS], co[3 * LEONAV_ORBIT_MAX_SLOTS], dx[NDX];
    for (int i = 0; i < NDX; ++i) {
        Kn[i] = bn[i] / S;
        cn[i] = bn[i] - S * Kn[i] / 2.0;
        dx[i] = Kn[i] * y;
    }
    for (int c = 0; c < mu; ++c) {
        Ko[c] = bo[c] / S;
        co[c] = bo[c] - S * Ko[c] / 2.0;
    }
    double x_new[NX];
    if (leonav_boxplus_many(1, x, dx, x_new, work) != LEONAV_OK) return LEONAV_FAILED;
    for (int i = 0; i < NX; ++i)
        if (!isfinite(x_new[i])) return LEONAV_FAILED;
    memcpy(x, x_new, sizeof x_new);
    /* the upper triangle once, mirrored: the generated steps read P's upper triangle, so P must
     * stay exactly symmetric whatever the compiler contracts (-ffp-contract) */
    for (int k = 0; k < NDX; ++k)
        for (int i = 0; i <= k; ++i) {
            P[i + k * NDX] -= Kn[i] * cn[k] + cn[i] * Kn[k];
            P[k + i * NDX] = P[i + k * NDX];
        }
    for (int c = 0; c < mu; ++c) {
        o->offset[c] += Ko[c] * y;
        double *pc = o->P_no + (size_t)c * NDX;
        for (int i = 0; i < NDX; ++i) pc[i] -= Kn[i] * co[c] + cn[i] * Ko[c];
        double *qc = o->P_oo + (size_t)c * m;
        const double kc = Ko[c], cc = co[c];
        for (int c2 = c; c2 < mu; ++c2) qc[c2] -= Ko[c2] * cc + co[c2] * kc;   /* lower triangle */
    }
    return LEONAV_OK;
}

/* ---- the run -------------------------------------------------------------------- */

int leonav_run_orbit(double *x, double *P, const double *p, const leonav_record *rec, long n,
                     const double *gate_nis, leonav_orbit_states *orb, leonav_run_out *out, void *work)
{
    if (!x || !P || !p || !out || !valid(orb) || (n > 0 && !rec) || n < 0 || out->P_lead < 0 || out->P_lead > NDX)
        return LEONAV_ERR_ARG;
    out->n_done = 0;
    out->n_imu = out->n_applied = out->n_gated = out->n_failed = out->n_cv = 0;
    /* the workspace check of the driver's steps (it comes before their kind check) */
    if (leonav_h_step(-1, x, NULL, p, NULL, NULL, work) == LEONAV_ERR_WORK) return LEONAV_ERR_WORK;
    leonav_symmetrize(P);   /* the navigation block, as leonav_run */
    long n_P = 0;
    for (long i = 0; i < n; ++i) {
        const leonav_record *r = &rec[i];
        double ysn[3] = {NAN, NAN, NAN};
        int step;
        if (r->kind == LEONAV_MEAS_IMU) {
            step = predict(x, P, r, p, orb, work);
            if (step == LEONAV_OK) out->n_imu++;
            if (step < 0) return step;
        } else if (r->kind >= 0 && r->kind < LEONAV_NMEAS) {
            step = update(x, P, r, p, gate_nis ? gate_nis[r->kind] : 0.0, orb, ysn, work);
            if (step == LEONAV_OK) out->n_applied++;
            if (step == LEONAV_GATED) out->n_gated++;
        } else {
            return LEONAV_ERR_KIND;   /* n_done: this record */
        }
        if (step == LEONAV_FAILED) out->n_failed++;
        if (out->x) memcpy(out->x + i * NX, x, sizeof(double) * NX);
        if (out->P_diag)
            for (int k = 0; k < NDX; ++k) out->P_diag[i * NDX + k] = P[k + k * NDX];
        if (out->P && (!out->P_mask || out->P_mask[i])) leonav_output_P(out, n_P++, P);
        if (out->y) out->y[i] = ysn[0];
        if (out->S) out->S[i] = ysn[1];
        if (out->nis) out->nis[i] = ysn[2];
        if (out->status)
            out->status[i] = step == LEONAV_FAILED ? LEONAV_STATUS_FAILED
                             : r->kind == LEONAV_MEAS_IMU ? LEONAV_STATUS_IMU
                             : step == LEONAV_GATED ? LEONAV_STATUS_GATED : LEONAV_STATUS_APPLIED;
        out->n_done = i + 1;
    }
    return LEONAV_OK;
}
