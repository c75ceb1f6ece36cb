/*
 * leonav driver: dispatch of records to the generated CasADi steps, gating, status codes.
 * See leonav_driver.h for the API contract. C99, no allocation, no exit.
 */
#include "leonav_driver.h"

#include <math.h>
#include <string.h>

#include "leonav_gen.h"

#define NX LEONAV_NX
#define NDX LEONAV_NDX
#define NU LEONAV_NU
#define NNAV LEONAV_NNAV
#define NMAT (LEONAV_NDX * LEONAV_NDX)
#define MAX_OUT 5     /* most outputs of any generated function the driver calls (update: 5) */
#define MAX_IN 6      /* most inputs of any generated function the driver calls (update: 6) */
#define WORK_MAGIC 0x6c656f6e61763031ULL

/* ---- table of generated functions ------------------------------------------------ */

typedef int (*gen_eval_fn)(const double **arg, double **res, int *iw, double *w, int mem);
typedef int (*gen_work_fn)(int *sz_arg, int *sz_res, int *sz_iw, int *sz_w);
typedef const int *(*gen_sparsity_fn)(int i);
typedef int (*gen_count_fn)(void);

typedef struct {
    gen_eval_fn eval;
    gen_work_fn work;
    gen_sparsity_fn sparsity_out;
    gen_count_fn n_out;
} gen_fn;

#define GEN_FN(name) {name, name##_work, name##_sparsity_out, name##_n_out}

typedef struct {
    gen_fn h;         /* leonav_h_<k>: h, H */
    gen_fn update;    /* leonav_update_<k>: Joseph-form scalar update */
    const char *name, *unit;
} meas_fns;

/* Kind id -> generated functions, built from the generated observable list
 * (state_layout.h), so a new observable in models/ needs no edit here. */
#define MEAS_ENTRY(id, k, dim, name, unit) \
    [id] = {GEN_FN(leonav_h_##k), GEN_FN(leonav_update_##k), name, unit},
static const meas_fns MEAS[LEONAV_NMEAS] = {LEONAV_MEAS_TABLE(MEAS_ENTRY)};

/* The driver's updates are scalar: a table entry with dimension != 1 fails to compile here. */
#define MEAS_SCALAR(id, k, dim, name, unit) &&(dim) == 1
typedef char meas_dims_are_scalar[(1 LEONAV_MEAS_TABLE(MEAS_SCALAR)) ? 1 : -1];

/* Kind id -> leonav_orbit_jac_<k> (dh/d satellite r, v in aux) for the observables in the
 * generated LEONAV_ORBIT_JAC_TABLE; other kinds have a zero entry (eval NULL). */
#define ORBIT_ENTRY(id, k) [id] = GEN_FN(leonav_orbit_jac_##k),
static const gen_fn ORBIT_JAC[LEONAV_NMEAS] = {LEONAV_ORBIT_JAC_TABLE(ORBIT_ENTRY)};

static const gen_fn MECH = GEN_FN(leonav_mech);
static const gen_fn PREDICT = GEN_FN(leonav_predict);
static const gen_fn PREDICT_CV = GEN_FN(leonav_predict_cv);    /* constant-velocity predict (no IMU) */
static const gen_fn BOXPLUS = GEN_FN(leonav_boxplus);
static const gen_fn GNSS_TERMS = GEN_FN(leonav_gnss_terms);     /* el, az, iono, tropo of a GNSS signal */
static const gen_fn BOXMINUS = GEN_FN(leonav_boxminus);
static const gen_fn PCRB_UPDATE = GEN_FN(leonav_pcrb_update);  /* B - B H^T H B / S, any observable */

/* ---- workspace ------------------------------------------------------------------- */

typedef struct {
    unsigned long long magic;
    const double **arg;         /* sz_arg entries */
    double **res;               /* sz_res entries */
    int *iw;                    /* sz_iw entries */
    double *w;                  /* sz_w entries */
    double nz[MAX_OUT][NMAT];   /* nonzeros of sparse outputs before scattering */
    double x_tmp[NX];
    double P_tmp[NMAT];
    double x_run[NX];           /* leonav_run's second state buffer (swapped, not copied) */
    double P_run[NMAT];
    double x_cov[NX];           /* leonav_run with a covariance interval: the interval's first state */
} workspace;

typedef struct {
    int sz_arg, sz_res, sz_iw, sz_w;
} work_sizes;

static void max_sizes(const gen_fn *f, work_sizes *m)
{
    int a = 0, r = 0, iw = 0, w = 0;
    f->work(&a, &r, &iw, &w);
    if (a > m->sz_arg) m->sz_arg = a;
    if (r > m->sz_res) m->sz_res = r;
    if (iw > m->sz_iw) m->sz_iw = iw;
    if (w > m->sz_w) m->sz_w = w;
}

static work_sizes all_sizes(void)
{
    work_sizes m = {MAX_IN, MAX_OUT, 0, 0};
    max_sizes(&MECH, &m);
    max_sizes(&PREDICT, &m);
    max_sizes(&PREDICT_CV, &m);
    max_sizes(&BOXPLUS, &m);
    max_sizes(&GNSS_TERMS, &m);
    max_sizes(&BOXMINUS, &m);
    max_sizes(&PCRB_UPDATE, &m);
    for (int k = 0; k < LEONAV_NMEAS; ++k) {
        max_sizes(&MEAS[k].h, &m);
        max_sizes(&MEAS[k].update, &m);
        if (ORBIT_JAC[k].eval) max_sizes(&ORBIT_JAC[k], &m);
    }
    return m;
}

static size_t align8(size_t n) { return (n + 7u) & ~(size_t)7u; }

size_t leonav_work_size(void)
{
    work_sizes m = all_sizes();
    return align8(sizeof(workspace)) + align8(sizeof(double *) * (size_t)m.sz_arg) +
           align8(sizeof(double *) * (size_t)m.sz_res) + sizeof(double) * (size_t)m.sz_w +
           align8(sizeof(int) * (size_t)m.sz_iw) + 8u;
}

static int outputs_fit(const gen_fn *f)
{
    for (int i = 0; i < f->n_out(); ++i) {
        const int *sp = f->sparsity_out(i);
        if (!sp || (long)sp[0] * sp[1] > NMAT) return 0;
    }
    return f->n_out() <= MAX_OUT;
}

/* h of a scalar observable: h is 1 x 1, H is 1 x NDX. */
static int h_is_scalar(const gen_fn *f)
{
    const int *h = f->sparsity_out(0), *H = f->sparsity_out(1);
    return f->n_out() == 2 && h && H && h[0] == 1 && h[1] == 1 && H[0] == 1 && H[1] == NDX;
}

int leonav_work_init(void *work, size_t nbytes)
{
    if (!work || nbytes < leonav_work_size()) return LEONAV_ERR_WORK;
    if (!outputs_fit(&MECH) || !outputs_fit(&PREDICT) || !outputs_fit(&PREDICT_CV) || !outputs_fit(&PCRB_UPDATE) ||
        !outputs_fit(&BOXPLUS) || !outputs_fit(&GNSS_TERMS))
        return LEONAV_ERR_LAYOUT;
    for (int k = 0; k < LEONAV_NMEAS; ++k)
        if (!outputs_fit(&MEAS[k].h) || !outputs_fit(&MEAS[k].update) || !h_is_scalar(&MEAS[k].h))
            return LEONAV_ERR_LAYOUT;
    work_sizes m = all_sizes();
    char *base = (char *)work;
    workspace *ws = (workspace *)base;
    memset(ws, 0, sizeof(workspace));
    size_t off = align8(sizeof(workspace));
    ws->arg = (const double **)(base + off);
    off += align8(sizeof(double *) * (size_t)m.sz_arg);
    ws->res = (double **)(base + off);
    off += align8(sizeof(double *) * (size_t)m.sz_res);
    ws->w = (double *)(base + off);
    off += sizeof(double) * (size_t)m.sz_w;
    ws->iw = (int *)(base + off);
    ws->magic = WORK_MAGIC;
    return LEONAV_OK;
}

static workspace *get_ws(void *work)
{
    workspace *ws = (workspace *)work;
    return (ws && ws->magic == WORK_MAGIC) ? ws : NULL;
}

/* ---- calling a generated function with dense outputs ------------------------------ */

/* CasADi sparsity: {nrow, ncol, 1} is dense; else {nrow, ncol, colind[ncol+1], row[nnz]}. */
static int is_dense(const int *sp) { return sp[2] == 1; }

static void scatter(const int *sp, const double *nz, double *dense)
{
    const int nrow = sp[0], ncol = sp[1];
    const int *colind = sp + 2, *row = sp + 3 + ncol;
    memset(dense, 0, sizeof(double) * (size_t)nrow * (size_t)ncol);
    for (int c = 0; c < ncol; ++c)
        for (int k = colind[c]; k < colind[c + 1]; ++k) dense[row[k] + c * nrow] = nz[k];
}

/* Evaluate f(in...) writing each non-NULL out[i] as a dense column-major matrix. */
static int call_gen(workspace *ws, const gen_fn *f, const double **in, int n_in, double **out, int n_out)
{
    for (int i = 0; i < n_in; ++i) ws->arg[i] = in[i];
    for (int i = 0; i < n_out; ++i) {
        if (!out[i]) ws->res[i] = NULL;
        else ws->res[i] = is_dense(f->sparsity_out(i)) ? out[i] : ws->nz[i];
    }
    if (f->eval(ws->arg, ws->res, ws->iw, ws->w, 0) != 0) return -1;
    for (int i = 0; i < n_out; ++i)
        if (out[i] && ws->res[i] == ws->nz[i]) scatter(f->sparsity_out(i), ws->nz[i], out[i]);
    return 0;
}

static int all_finite(const double *v, int n)
{
    for (int i = 0; i < n; ++i)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* ---- steps ----------------------------------------------------------------------- */

int leonav_mech_step(double *x, const double *u, double dt, const double *p, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (!all_finite(u, NU) || !isfinite(dt) || dt < 0.0) return LEONAV_FAILED;
    const double *in[4] = {x, u, &dt, p};
    double *out[1] = {ws->x_tmp};
    if (call_gen(ws, &MECH, in, 4, out, 1) != 0 || !all_finite(ws->x_tmp, NX)) return LEONAV_FAILED;
    memcpy(x, ws->x_tmp, sizeof(double) * NX);
    return LEONAV_OK;
}

int leonav_boxminus_many(long n, const double *x1, const double *x0, double *dx, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (n < 0 || !x1 || !x0 || !dx) return LEONAV_ERR_ARG;
    for (long i = 0; i < n; ++i) {
        const double *in[2] = {x1 + i * NX, x0 + i * NX};
        double *out[1] = {dx + i * NDX};
        if (call_gen(ws, &BOXMINUS, in, 2, out, 1) != 0) return LEONAV_ERR_NUMERIC;
    }
    return LEONAV_OK;
}

/* A state is usable when x and the variances (diagonal of P) are finite. The diagonal is
 * where a NaN or Inf anywhere in P ends up after one predict or update, and checking it
 * instead of all NDX^2 entries keeps the check off the hot path's profile. */
static int state_finite(const double *x, const double *P)
{
    if (!all_finite(x, NX)) return 0;
    for (int i = 0; i < NDX; ++i)
        if (!isfinite(P[i + i * NDX])) return 0;
    return 1;
}

/* Predict (x, P) into (x_out, P_out); the inputs are left as they are. */
static int predict_into(workspace *ws, const double *x, const double *P, const double *u, double dt,
                        const double *p, double *x_out, double *P_out, double *F, double *Qd)
{
    if (!all_finite(u, NU) || !isfinite(dt) || dt < 0.0) return LEONAV_FAILED;
    const double *in[5] = {x, P, u, &dt, p};
    double *out[4] = {x_out, P_out, F, Qd};
    if (call_gen(ws, &PREDICT, in, 5, out, 4) != 0 || !state_finite(x_out, P_out)) return LEONAV_FAILED;
    return LEONAV_OK;
}

/* Constant-velocity predict of (x, P) over dt into (x_out, P_out); the inputs are left as they are. */
static int predict_cv_into(workspace *ws, const double *x, const double *P, double dt, const double *p,
                           double *x_out, double *P_out, double *F, double *Qd)
{
    if (!isfinite(dt) || dt < 0.0) return LEONAV_FAILED;
    const double *in[4] = {x, P, &dt, p};
    double *out[4] = {x_out, P_out, F, Qd};
    if (call_gen(ws, &PREDICT_CV, in, 4, out, 4) != 0 || !state_finite(x_out, P_out)) return LEONAV_FAILED;
    return LEONAV_OK;
}

/* Scalar update of (x, P) into (x_out, P_out); returns LEONAV_OK, _GATED or _FAILED and
 * writes y, S, nis into ysn (NaN where not computed). */
static int update_into(workspace *ws, const double *x, const double *P, int kind, double z, double R,
                       const double *aux, const double *p, double gate_nis, double *ysn,
                       double *x_out, double *P_out)
{
    ysn[0] = ysn[1] = ysn[2] = NAN;
    if (!isfinite(z) || !isfinite(R) || !all_finite(aux, LEONAV_NAUX)) return LEONAV_FAILED;
    const double *in[6] = {x, P, &z, &R, aux, p};
    double *out[5] = {x_out, P_out, &ysn[0], &ysn[1], &ysn[2]};
    /* R < 0 is still evaluated so that its S is reported with the failure */
    if (call_gen(ws, &MEAS[kind].update, in, 6, out, 5) != 0 || R < 0.0 || !(ysn[1] > 0.0) || !isfinite(ysn[1]) ||
        !isfinite(ysn[2]) || !state_finite(x_out, P_out))
        return LEONAV_FAILED;
    if (gate_nis > 0.0 && ysn[2] > gate_nis) return LEONAV_GATED;
    return LEONAV_OK;
}

int leonav_predict_step(double *x, double *P, const double *u, double dt, const double *p,
                        double *F, double *Qd, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    int status = predict_into(ws, x, P, u, dt, p, ws->x_tmp, ws->P_tmp, F, Qd);
    if (status == LEONAV_OK) {
        memcpy(x, ws->x_tmp, sizeof(double) * NX);
        memcpy(P, ws->P_tmp, sizeof(double) * NMAT);
    }
    return status;
}

int leonav_predict_cv_step(double *x, double *P, double dt, const double *p, double *F, double *Qd, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    int status = predict_cv_into(ws, x, P, dt, p, ws->x_tmp, ws->P_tmp, F, Qd);
    if (status == LEONAV_OK) {
        memcpy(x, ws->x_tmp, sizeof(double) * NX);
        memcpy(P, ws->P_tmp, sizeof(double) * NMAT);
    }
    return status;
}

int leonav_update_step(double *x, double *P, int kind, double z, double R, const double *aux,
                       const double *p, double gate_nis, double *y_S_nis, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (kind < 0 || kind >= LEONAV_NMEAS) return LEONAV_ERR_KIND;
    double ysn[3];
    int status = update_into(ws, x, P, kind, z, R, aux, p, gate_nis, ysn, ws->x_tmp, ws->P_tmp);
    if (status == LEONAV_OK) {
        memcpy(x, ws->x_tmp, sizeof(double) * NX);
        memcpy(P, ws->P_tmp, sizeof(double) * NMAT);
    }
    if (y_S_nis) memcpy(y_S_nis, ysn, sizeof ysn);
    return status;
}

int leonav_h_step(int kind, const double *x, const double *aux, const double *p, double *h,
                  double *H, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (kind < 0 || kind >= LEONAV_NMEAS) return LEONAV_ERR_KIND;
    const double *in[3] = {x, aux, p};
    double *out[2] = {h, H};
    if (call_gen(ws, &MEAS[kind].h, in, 3, out, 2) != 0) return LEONAV_FAILED;
    if ((h && !isfinite(*h)) || (H && !all_finite(H, NDX))) return LEONAV_FAILED;
    return LEONAV_OK;
}

int leonav_h_many(int kind, long n, const double *x, const double *aux, const double *p, double *h,
                  double *H, int32_t *status, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (kind < 0 || kind >= LEONAV_NMEAS) return LEONAV_ERR_KIND;
    if (n < 0 || (n > 0 && (!x || !aux || !p || !h))) return LEONAV_ERR_ARG;
    for (long i = 0; i < n; ++i) {
        double *Hi = H ? H + i * NDX : NULL;
        int rc = leonav_h_step(kind, x + i * NX, aux + i * LEONAV_NAUX, p, h + i, Hi, work);
        if (rc < 0) return rc;
        if (rc != LEONAV_OK) {
            h[i] = NAN;
            if (Hi)
                for (int j = 0; j < NDX; ++j) Hi[j] = NAN;
        }
        if (status) status[i] = rc;
    }
    return LEONAV_OK;
}

int leonav_gnss_terms_many(long n, const double *x, const double *aux, const double *p, double *terms, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (n < 0 || (n > 0 && (!x || !aux || !p || !terms))) return LEONAV_ERR_ARG;
    for (long i = 0; i < n; ++i) {
        const double *in[3] = {x + i * NX, aux + i * LEONAV_NAUX, p};
        double *out[1] = {terms + 4 * i};
        if (call_gen(ws, &GNSS_TERMS, in, 3, out, 1) != 0 || !all_finite(terms + 4 * i, 4))
            for (int j = 0; j < 4; ++j) terms[4 * i + j] = NAN;
    }
    return LEONAV_OK;
}

int leonav_orbit_jacobian_many(int kind, long n, const double *x, const double *aux, const double *p, double *J,
                               void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (kind < 0 || kind >= LEONAV_NMEAS || !ORBIT_JAC[kind].eval) return LEONAV_ERR_KIND;
    if (n < 0 || (n > 0 && (!x || !aux || !p || !J))) return LEONAV_ERR_ARG;
    for (long i = 0; i < n; ++i) {
        const double *in[3] = {x + i * NX, aux + i * LEONAV_NAUX, p};
        double *Ji = J + i * LEONAV_NORBIT;
        double *out[1] = {Ji};
        if (call_gen(ws, &ORBIT_JAC[kind], in, 3, out, 1) != 0 || !all_finite(Ji, LEONAV_NORBIT))
            for (int j = 0; j < LEONAV_NORBIT; ++j) Ji[j] = NAN;
    }
    return LEONAV_OK;
}

int leonav_boxplus_many(long n, const double *x, const double *dx, double *x_out, void *work)
{
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    if (n < 0 || (n > 0 && (!x || !dx || !x_out))) return LEONAV_ERR_ARG;
    for (long i = 0; i < n; ++i) {
        const double *in[2] = {x + i * NX, dx + i * NDX};
        double *out[1] = {ws->x_tmp};
        if (call_gen(ws, &BOXPLUS, in, 2, out, 1) != 0) return LEONAV_ERR_NUMERIC;
        memcpy(x_out + i * NX, ws->x_tmp, sizeof(double) * NX);  /* x_out may alias x */
    }
    return LEONAV_OK;
}

const char *leonav_code_name(int rc)
{
#define CODE_CASE(name) case LEONAV_##name: return "LEONAV_" #name;
    switch (rc) { LEONAV_RETURN_CODE_TABLE(CODE_CASE) }
#undef CODE_CASE
    return "LEONAV_?";
}

const char *leonav_meas_name(int kind) { return kind >= 0 && kind < LEONAV_NMEAS ? MEAS[kind].name : NULL; }

const char *leonav_meas_unit(int kind) { return kind >= 0 && kind < LEONAV_NMEAS ? MEAS[kind].unit : NULL; }

/* ---- whole runs ------------------------------------------------------------------ */

static void diag(const double *M, double *d)
{
    for (int i = 0; i < NDX; ++i) d[i] = M[i + i * NDX];
}

/* Per-record status (its own enum, leonav_driver.h) of a step's return code. */
static int32_t record_status(int kind, int rc)
{
    if (rc == LEONAV_FAILED) return LEONAV_STATUS_FAILED;
    if (kind == LEONAV_MEAS_IMU || kind == LEONAV_KIND_CV) return LEONAV_STATUS_IMU;
    return rc == LEONAV_GATED ? LEONAV_STATUS_GATED : LEONAV_STATUS_APPLIED;
}

/* Nominal mechanization of x over one IMU record into x_out (x is left as it is). */
static int mech_into(workspace *ws, const double *x, const double *u, double dt, const double *p, double *x_out)
{
    if (!all_finite(u, NU) || !isfinite(dt) || dt < 0.0) return LEONAV_FAILED;
    const double *in[4] = {x, u, &dt, p};
    double *out[1] = {x_out};
    if (call_gen(ws, &MECH, in, 4, out, 1) != 0 || !all_finite(x_out, NX)) return LEONAV_FAILED;
    return LEONAV_OK;
}

void leonav_symmetrize(double *M)
{
    for (int j = 0; j < NDX; ++j)
        for (int i = 0; i < j; ++i) M[i + j * NDX] = M[j + i * NDX] = (M[i + j * NDX] + M[j + i * NDX]) / 2;
}

void leonav_output_P(const leonav_run_out *out, long k, const double *P)
{
    long m = out->P_lead > 0 ? out->P_lead : NDX;
    double *dst = out->P + k * m * m;
    if (m == NDX) {
        memcpy(dst, P, sizeof(double) * NMAT);
        return;
    }
    for (long j = 0; j < m; ++j) memcpy(dst + j * m, P + j * NDX, sizeof(double) * m);
}

/* IMU records whose covariance step is still to come (leonav_run with cov_interval > 0). */
typedef struct {
    long n;            /* records mechanized since the last covariance step */
    long first;        /* the run's first mechanized record */
    double u[NU];      /* their increments, summed (body FLU, as each record's) */
    double dt;         /* their intervals, summed, s */
} cov_pending;

/* A run whose covariance step failed at record `last`: each of its earlier records becomes the
 * failed predict it is in the per-sample loop (status, counts, x at the run's first state,
 * P_diag of the P kept), so the outputs say where the state is once the run is undone. `ok`:
 * how many of them were mechanized (and counted in n_imu). */
static void fail_run(const cov_pending *c, long last, long ok, const double *x_first, const double *P,
                     leonav_run_out *out)
{
    out->n_imu -= ok;
    out->n_failed += ok;
    for (long k = c->first; k < last; ++k) {
        if (out->x) memcpy(out->x + k * NX, x_first, sizeof(double) * NX);
        if (out->P_diag) diag(P, out->P_diag + k * NDX);
        if (out->status) out->status[k] = LEONAV_STATUS_FAILED;
    }
}

/* Whether record i ends a run of the covariance interval: the run's summed dt has reached the
 * interval (so a run can exceed it by less than one record's dt), its P is an output, or the
 * next record is not an IMU record (an update or a CV predict reads P). */
static int ends_interval(const cov_pending *c, double cov_interval, const leonav_record *rec, long i, long n,
                         const leonav_run_out *out)
{
    if (c->dt >= cov_interval * (1.0 - 1e-9)) return 1;
    if (out->P && (!out->P_mask || out->P_mask[i])) return 1;
    return i + 1 >= n || rec[i + 1].kind != LEONAV_MEAS_IMU;
}

int leonav_run(double *x, double *P, const double *p, const leonav_record *rec, long n,
               const double *gate_nis, double cov_interval, leonav_run_out *out, void *work)
{
    if (!x || !P || !p || !out || (n > 0 && !rec) || n < 0 || !(cov_interval >= 0.0) || !isfinite(cov_interval)
        || out->P_lead < 0 || out->P_lead > NDX)
        return LEONAV_ERR_ARG;
    out->n_done = 0;
    out->n_imu = out->n_applied = out->n_gated = out->n_failed = out->n_cv = 0;
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    leonav_symmetrize(P);   /* the generated steps read its upper triangle */
    /* The state lives in one of two buffers (the caller's, the workspace's); a step writes
     * the other one and they are swapped when it succeeds, so nothing is copied. x and P
     * swap apart: a mechanization alone writes x only, a deferred covariance step P only. */
    double *xc = x, *Pc = P, *xn = ws->x_run, *Pn = ws->P_run;
    long n_P = 0;  /* full-P blocks written */
    int rc = LEONAV_OK;
    cov_pending cov = {0, 0, {0.0}, 0.0};
    for (long i = 0; i < n; ++i) {
        const leonav_record *r = &rec[i];
        double ysn[3] = {NAN, NAN, NAN};
        int step, P_current = 1;
        int wrote_x, wrote_P;  /* which of the other buffers this record wrote */
        if (r->kind == LEONAV_MEAS_IMU && cov_interval > 0.0) {
            /* mechanize now; propagate P once per interval, over the summed increments from
             * the interval's first state (docs/design.md, "Covariance interval") */
            step = mech_into(ws, xc, r->u, r->dt, p, xn);
            wrote_x = step == LEONAV_OK;
            wrote_P = 0;
            if (wrote_x) {
                if (cov.n == 0) {
                    memcpy(ws->x_cov, xc, sizeof(double) * NX);
                    cov.first = i;
                }
                for (int k = 0; k < NU; ++k) cov.u[k] += r->u[k];
                cov.dt += r->dt;
                cov.n++;
            }
            if (cov.n > 0 && ends_interval(&cov, cov_interval, rec, i, n, out)) {
                wrote_P = predict_into(ws, ws->x_cov, Pc, cov.u, cov.dt, p, ws->x_tmp, Pn, NULL, NULL) == LEONAV_OK;
                if (!wrote_P) {   /* the run fails whole: x back to its first state, P kept */
                    memcpy(xn, ws->x_cov, sizeof(double) * NX);
                    wrote_x = 1;
                    /* cov.n counts this record too when its own mechanization succeeded */
                    fail_run(&cov, i, cov.n - (step == LEONAV_OK), ws->x_cov, Pc, out);
                    step = LEONAV_FAILED;
                }
                cov = (cov_pending){0, 0, {0.0}, 0.0};
            }
            P_current = cov.n == 0;
            if (step == LEONAV_OK) out->n_imu++;
        } else {
            if (r->kind == LEONAV_MEAS_IMU) {
                step = predict_into(ws, xc, Pc, r->u, r->dt, p, xn, Pn, NULL, NULL);
                if (step == LEONAV_OK) out->n_imu++;
            } else if (r->kind == LEONAV_KIND_CV) {
                step = predict_cv_into(ws, xc, Pc, r->dt, p, xn, Pn, NULL, NULL);
                if (step == LEONAV_OK) out->n_cv++;
            } else if (r->kind >= 0 && r->kind < LEONAV_NMEAS) {
                double gate = gate_nis ? gate_nis[r->kind] : 0.0;
                step = update_into(ws, xc, Pc, r->kind, r->z, r->R, r->aux, p, gate, ysn, xn, Pn);
                if (step == LEONAV_OK) out->n_applied++;
                if (step == LEONAV_GATED) out->n_gated++;
            } else {
                rc = LEONAV_ERR_KIND;
                break;
            }
            wrote_x = wrote_P = step == LEONAV_OK;
        }
        if (wrote_x) { double *t = xc; xc = xn; xn = t; }
        if (wrote_P) { double *t = Pc; Pc = Pn; Pn = t; }
        if (step == LEONAV_FAILED) out->n_failed++;
        if (out->x) memcpy(out->x + i * NX, xc, sizeof(double) * NX);
        if (out->P_diag) {
            if (P_current) diag(Pc, out->P_diag + i * NDX);
            else for (int k = 0; k < NDX; ++k) out->P_diag[i * NDX + k] = NAN;
        }
        if (out->P && (!out->P_mask || out->P_mask[i])) leonav_output_P(out, n_P++, Pc);
        if (out->y) out->y[i] = ysn[0];
        if (out->S) out->S[i] = ysn[1];
        if (out->nis) out->nis[i] = ysn[2];
        if (out->status) out->status[i] = record_status(r->kind, step);
        out->n_done = i + 1;
    }
    if (xc != x) memcpy(x, xc, sizeof(double) * NX);   /* the state ends in the caller's buffers */
    if (Pc != P) memcpy(P, Pc, sizeof(double) * NMAT);
    return rc;
}

int leonav_pcrb_run(double *B, const double *p, const leonav_record *rec, long n,
                    const double *x_lin, double *B_diag, double *B_nav, double *B_full,
                    long *n_done, void *work)
{
    long done_dummy = 0;
    if (!n_done) n_done = &done_dummy;
    *n_done = 0;
    if (!B || !p || n < 0 || (n > 0 && (!rec || !x_lin))) return LEONAV_ERR_ARG;
    workspace *ws = get_ws(work);
    if (!ws) return LEONAV_ERR_WORK;
    leonav_symmetrize(B);   /* the generated predict reads its upper triangle */
    for (long i = 0; i < n; ++i) {
        const leonav_record *r = &rec[i];
        const double *xi = x_lin + i * NX;
        if (r->kind == LEONAV_MEAS_IMU) {
            /* predict with P = B gives exactly F B F^T + Qd; the state output is discarded */
            double x_copy[NX];
            memcpy(x_copy, xi, sizeof x_copy);
            if (leonav_predict_step(x_copy, B, r->u, r->dt, p, NULL, NULL, work) != LEONAV_OK)
                return LEONAV_ERR_NUMERIC;
        } else if (r->kind == LEONAV_KIND_CV) {
            double x_copy[NX];
            memcpy(x_copy, xi, sizeof x_copy);
            if (leonav_predict_cv_step(x_copy, B, r->dt, p, NULL, NULL, work) != LEONAV_OK)
                return LEONAV_ERR_NUMERIC;
        } else if (r->kind >= 0 && r->kind < LEONAV_NMEAS) {
            /* H of leonav_h_<kind> at xi, then the generated Sherman-Morrison step on B */
            double h, H[NDX], S = NAN;
            if (leonav_h_step(r->kind, xi, r->aux, p, &h, H, work) != LEONAV_OK) return LEONAV_ERR_NUMERIC;
            const double *in[3] = {B, H, &r->R};
            double *out[2] = {ws->P_tmp, &S};
            if (call_gen(ws, &PCRB_UPDATE, in, 3, out, 2) != 0 || !(S > 0.0) || !isfinite(S) || !(r->R > 0.0))
                return LEONAV_ERR_NUMERIC;
            memcpy(B, ws->P_tmp, sizeof(double) * NMAT);
        } else {
            return LEONAV_ERR_KIND;
        }
        if (B_diag) diag(B, B_diag + i * NDX);
        if (B_nav)  /* the 9D block leads dx (dx[0:NNAV], state_layout.h) */
            for (int b = 0; b < NNAV; ++b)
                for (int a = 0; a < NNAV; ++a) B_nav[i * NNAV * NNAV + a + b * NNAV] = B[a + b * NDX];
        if (B_full) memcpy(B_full + i * NMAT, B, sizeof(double) * NMAT);
        *n_done = i + 1;
    }
    return LEONAV_OK;
}
