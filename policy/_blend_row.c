/* policy._blend_row: `policy.blend_fast.blend_row_python` (SL / NAIL / AAIL of one row, paper
 * §3.3, eqs. 8-10) compiled, with the same bits.
 *
 * Why C: at batch 1 the row blend is ~20 µs of Python float arithmetic when the interpreter's
 * caches are warm, and 60-100 µs when the networks' weights have just streamed through the CPU
 * caches (a server between requests): most of a single act's engine time. Here the arithmetic
 * is a few hundred double operations, and the transcendental functions are still numpy's.
 *
 * How the bits stay those of `policy.blend_fast` (and so of `policy.blend`'s vectorised path):
 * - + - * / and sqrt are IEEE operations in Python floats and C doubles alike; the build turns
 *   off contraction into fused multiply-adds (-ffp-contract=off, setup.py), which would round
 *   once where Python rounds twice.
 * - exp, log, log2 and power are numpy's ufuncs, called on float64 arrays as blend_fast calls
 *   them (numpy's SIMD versions can differ from libm in the last bit).
 * - Sums are in the order blend_fast documents: sequential below 8 terms, numpy's pairwise
 *   order from 8 on (`vsum`); Python's max/min keep the first of equal values (`first_max`).
 * The Python module stays the reference: tests compare both on random and ill-conditioned rows.
 *
 * Inputs are trusted as blend_fast's are (finite, alpha > 0, vectors of one length A >= 1);
 * anything that is not a sequence of floats raises TypeError.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include "_numpy_order.h"

#define FLAT_STD_RTOL 1e-12 /* blend_fast.FLAT_STD_RTOL */

static PyObject *np_exp, *np_log, *np_log2, *np_power, *row_blend_type;

/* the sum over actions: blend_fast's `vsum` */
static double vsum(const double *x, Py_ssize_t n, Py_ssize_t n_act) {
    return n_act < 8 ? sequential_sum(x, n) : pairwise_sum(x, n);
}

static double first_max(const double *x, Py_ssize_t n) { /* Python's max(): first of equals */
    double best = x[0];
    for (Py_ssize_t i = 1; i < n; i++)
        if (x[i] > best) best = x[i];
    return best;
}

static double first_min(const double *x, Py_ssize_t n) {
    double best = x[0];
    for (Py_ssize_t i = 1; i < n; i++)
        if (x[i] < best) best = x[i];
    return best;
}

static double py_max2(double a, double b) { return b > a ? b : a; } /* max(a, b) */
static double py_min2(double a, double b) { return b < a ? b : a; } /* min(a, b) */

/* float(np.log(n)) for an action count n, as blend_fast._log (cached: n is small) */
#define LOG_CACHE 64
static double log_cache[LOG_CACHE];

static int log_of_count(Py_ssize_t n, double *out) {
    if (n < LOG_CACHE && log_cache[n] != 0.0) {
        *out = log_cache[n];
        return 0;
    }
    PyObject *count = PyLong_FromSsize_t(n);
    if (count == NULL) return -1;
    PyObject *value = PyObject_CallOneArg(np_log, count);
    Py_DECREF(count);
    if (value == NULL) return -1;
    *out = PyFloat_AsDouble(value);
    Py_DECREF(value);
    if (*out == -1.0 && PyErr_Occurred()) return -1;
    if (n < LOG_CACHE) log_cache[n] = *out;
    return 0;
}

/* ---- the steps of blend_fast, B rows at a time --------------------------------------------
 * Each step runs over every row, then calls its ufunc once for all of them (a ufunc's result
 * for one element does not depend on the others): 5 numpy calls per batch, not per row. Per
 * row the operations and their order are those of blend_fast's functions named below. */

enum { SL, NAIL, AAIL };

typedef struct {
    Py_ssize_t B, P, n;
    int method, normalise;
    const double *q_task;   /* (B, n) */
    const double *q_impact; /* (B, P, n): masked rows are never read */
    const double *alpha;    /* (B,) */
    const char *mask;       /* (B, P) */
    double *q, *probs, *entropy, *weight, *partner_weights; /* out: (B, n) (B, n) (B) (B) (B, P) */
} Batch;

typedef struct { /* working memory, one block */
    Py_ssize_t *active, *policy_at, *pair_at; /* per row: active slots, first policy, first JS pair */
    double *policies;                         /* the Boltzmann policies: task, then active impacts */
    double *p_once, *p_twice, *logs;          /* (B, n) (B, n) (B, 2n) */
    double *h_eq9;                            /* (B) */
    double *num, *ratio;                      /* JS terms: per row 2 k n each */
    double *z, *scales;                       /* one row's z-scores ((P + 1) n) and scales (P) */
} Work;

/* _boltzmann's exp step: out[i] = exp((q - max q) / alpha) for `count` vectors of n */
static void boltzmann_inputs(const double *q, Py_ssize_t count, Py_ssize_t n, double alpha,
                             double *out) {
    for (Py_ssize_t v = 0; v < count; v++) {
        const double *row = q + v * n;
        double top = first_max(row, n);
        for (Py_ssize_t a = 0; a < n; a++) out[v * n + a] = (row[a] - top) / alpha;
    }
}

static void boltzmann_finish(double *e, Py_ssize_t count, Py_ssize_t n) {
    for (Py_ssize_t v = 0; v < count; v++, e += n) {
        double total = vsum(e, n, n);
        for (Py_ssize_t a = 0; a < n; a++) e[a] = e[a] / total;
    }
}

/* _renormalised, into `out` (p itself when its sum is exactly 1) */
static void renormalised(const double *p, Py_ssize_t n, double *out) {
    double total = vsum(p, n, n);
    for (Py_ssize_t a = 0; a < n; a++) out[a] = total == 1.0 ? p[a] : p[a] / total;
}

/* _entropies, the step after numpy's log: logs[a] = log(p[a] > 0 ? p[a] : 1) */
static double entropy_finish(const double *p, const double *logs, Py_ssize_t n, double log_n) {
    double terms[PAIRWISE_BLOCK];
    double *t = n <= PAIRWISE_BLOCK ? terms : PyMem_Malloc(n * sizeof(double));
    if (t == NULL) { /* out of memory: the caller checks PyErr_Occurred() */
        PyErr_NoMemory();
        return 0.0;
    }
    for (Py_ssize_t a = 0; a < n; a++) t[a] = p[a] > 0 ? p[a] * logs[a] : 0.0;
    double h = -vsum(t, n, n) / log_n;
    if (t != terms) PyMem_Free(t);
    return py_min2(py_max2(h, 0.0), 1.0);
}

/* _standardise: z into `z`, the scale returned; z = 0 and scale 0 when flat */
static double standardise(const double *q, Py_ssize_t n, double *z, double *squares) {
    double magnitude = py_max2(first_max(q, n), -first_min(q, n));
    double divisor = magnitude > 0 ? magnitude : 1.0;
    for (Py_ssize_t a = 0; a < n; a++) z[a] = q[a] / divisor;
    double mean = vsum(z, n, n) / n;
    for (Py_ssize_t a = 0; a < n; a++) {
        z[a] = z[a] - mean; /* the deviations */
        squares[a] = z[a] * z[a];
    }
    double std = sqrt(vsum(squares, n, n) / n);
    if (std <= FLAT_STD_RTOL) {
        for (Py_ssize_t a = 0; a < n; a++) z[a] = 0.0;
        return 0.0;
    }
    for (Py_ssize_t a = 0; a < n; a++) z[a] = z[a] / std;
    return std * magnitude;
}

/* step 1: the Boltzmann policies of the task and (aail) of each active impact (_boltzmann) */
static int policies_step(const Batch *t, Work *w) {
    Py_ssize_t n = t->n, at = 0;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        w->policy_at[b] = at;
        boltzmann_inputs(t->q_task + b * n, 1, n, t->alpha[b], w->policies + at);
        at += n;
        if (t->method != AAIL) continue;
        for (Py_ssize_t s = 0; s < t->P; s++)
            if (t->mask[b * t->P + s]) {
                boltzmann_inputs(t->q_impact + (b * t->P + s) * n, 1, n, t->alpha[b],
                                 w->policies + at);
                at += n;
            }
    }
    if (ufunc_inplace(np_exp, w->policies, at) < 0) return -1;
    boltzmann_finish(w->policies, at / n, n);
    return 0;
}

/* step 2: the task policy's normalised entropy, and eq. 9's (aail) on it renormalised twice */
static int entropy_step(const Batch *t, Work *w) {
    Py_ssize_t n = t->n;
    double log_n = 0.0;
    if (n > 1 && log_of_count(n, &log_n) < 0) return -1;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        double *once = w->p_once + b * n, *twice = w->p_twice + b * n, *logs = w->logs + 2 * b * n;
        renormalised(w->policies + w->policy_at[b], n, once); /* as normalized_entropy sees it */
        renormalised(once, n, twice);                         /* as eq. 9's task_weight sees it */
        for (Py_ssize_t a = 0; a < n; a++) {
            logs[a] = once[a] > 0 ? once[a] : 1.0;
            logs[n + a] = twice[a] > 0 ? twice[a] : 1.0;
        }
    }
    if (n > 1 && ufunc_inplace(np_log, w->logs, 2 * t->B * n) < 0) return -1;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        const double *logs = w->logs + 2 * b * n;
        t->entropy[b] = n > 1 ? entropy_finish(w->p_once + b * n, logs, n, log_n) : 0.0;
        w->h_eq9[b] = n > 1 ? entropy_finish(w->p_twice + b * n, logs + n, n, log_n) : 0.0;
    }
    return PyErr_Occurred() ? -1 : 0;
}

/* step 3 (aail): eq. 10, the JS distance of the task policy to each active impact policy
 * (_js_distances), into partner_weights' active slots; then the weights ŵ (_aail) */
static int js_step(const Batch *t, Work *w) {
    Py_ssize_t n = t->n, P = t->P, at = 0;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        Py_ssize_t k = w->active[b], half = k * n;
        const double *p = w->p_once + b * n;
        double *num = w->num + at, *den = w->ratio + at; /* num = p_rep + q_flat, den = m + m */
        w->pair_at[b] = at;
        for (Py_ssize_t v = 0; v < k; v++) /* the impact policies, renormalised */
            renormalised(w->policies + w->policy_at[b] + (v + 1) * n, n, num + half + v * n);
        for (Py_ssize_t i = 0; i < half; i++) {
            num[i] = p[i % n];
            den[i] = den[half + i] = 0.5 * (num[i] + num[half + i]);
        }
        int regular = half == 0 || (first_min(num, 2 * half) > 0 && first_min(den, half) > 0);
        for (Py_ssize_t i = 0; i < 2 * half; i++) {
            if (regular)
                den[i] = num[i] / den[i];
            else /* numpy: 1 where the numerator is 0 (the term is 0), inf where m underflowed */
                den[i] = num[i] > 0 ? (den[i] > 0 ? num[i] / den[i] : Py_HUGE_VAL) : 1.0;
        }
        at += 2 * half;
    }
    if (at > 0 && ufunc_inplace(np_log2, w->ratio, at) < 0) return -1;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        Py_ssize_t k = w->active[b], half = k * n, next = 0;
        double *terms = w->ratio + w->pair_at[b];
        const double *num = w->num + w->pair_at[b];
        for (Py_ssize_t i = 0; i < 2 * half; i++) /* x log2(x / m), 0 where x = 0 */
            terms[i] = num[i] > 0 ? num[i] * terms[i] : 0.0;
        double *weights = t->partner_weights + b * P;
        for (Py_ssize_t s = 0; s < P; s++) {
            weights[s] = 0.0;
            if (!t->mask[b * P + s]) continue;
            double kl_p = vsum(terms + next * n, n, n), kl_q = vsum(terms + half + next * n, n, n);
            weights[s] = sqrt(py_min2(py_max2(0.5 * kl_p + 0.5 * kl_q, 0.0), 1.0));
            next++;
        }
        double total = pairwise_sum(weights, P);
        for (Py_ssize_t s = 0; s < P; s++) {
            if (total > 0)
                weights[s] = weights[s] / total;
            else /* every impact policy equals the task policy: equal shares */
                weights[s] = t->mask[b * P + s] ? 1.0 / (k > 1 ? k : 1) : 0.0;
        }
    }
    return 0;
}

/* step 4: the blended Q of each row: sl the task's, nail the raw mean (_nail), aail eq. 8
 * standardised (_aail) or raw (_aail_raw) */
static void blend_step(const Batch *t, Work *w, const double *power) {
    Py_ssize_t n = t->n, P = t->P;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        const double *q_task = t->q_task + b * n, *q_impact = t->q_impact + b * P * n;
        const char *mask = t->mask + b * P;
        double *q = t->q + b * n, *weights = t->partner_weights + b * P;
        Py_ssize_t k = w->active[b];
        if (t->method == SL) {
            memcpy(q, q_task, n * sizeof(double));
            memset(weights, 0, P * sizeof(double));
            t->weight[b] = 1.0;
            continue;
        }
        if (t->method == NAIL) {
            if (n == 1) { /* numpy then sums over the contiguous partner axis: pairwise */
                for (Py_ssize_t s = 0; s < P; s++) w->scales[s] = mask[s] ? q_impact[s * n] : 0.0;
                q[0] = pairwise_sum(w->scales, P);
            } else { /* numpy adds the partners' vectors one after the other */
                memset(q, 0, n * sizeof(double));
                for (Py_ssize_t s = 0; s < P; s++)
                    if (mask[s])
                        for (Py_ssize_t a = 0; a < n; a++) q[a] = q[a] + q_impact[s * n + a];
            }
            for (Py_ssize_t a = 0; a < n; a++) q[a] = (q_task[a] + q[a]) / (1.0 + k);
            for (Py_ssize_t s = 0; s < P; s++) weights[s] = mask[s] ? 1.0 / (k > 1 ? k : 1) : 0.0;
            t->weight[b] = 1.0 / (1.0 + k);
            continue;
        }
        /* eq. 9, w_t = 1 - |A|^H / |A|; the task alone without an active partner */
        double w_t = k > 0 ? (n > 1 ? 1.0 - power[b] / n : 1.0) : 1.0;
        t->weight[b] = w_t;
        if (!t->normalise) { /* Q_C = w_t Q_t + (1 - w_t) Σ_i ŵ_i Q_i */
            for (Py_ssize_t a = 0; a < n; a++) {
                double mixed = 0.0; /* partners in order (numpy's einsum order) */
                for (Py_ssize_t s = 0; s < P; s++)
                    if (mask[s]) mixed += weights[s] * q_impact[s * n + a];
                q[a] = w_t * q_task[a] + (1.0 - w_t) * mixed;
            }
            continue;
        }
        double *z_task = w->z, *z_impact = w->z + n, *squares = q; /* q: scratch until the end */
        double s_task = standardise(q_task, n, z_task, squares);
        for (Py_ssize_t s = 0; s < P; s++) /* masked slots: z = 0 and scale 0 */
            w->scales[s] = mask[s] ? weights[s] * standardise(q_impact + s * n, n,
                                                              z_impact + s * n, squares)
                                   : weights[s] * 0.0;
        double s_blend = w_t * s_task + (1.0 - w_t) * pairwise_sum(w->scales, P);
        for (Py_ssize_t a = 0; a < n; a++) {
            double mixed = 0.0; /* Σ_i ŵ_i z_i, partners in order */
            for (Py_ssize_t s = 0; s < P; s++)
                if (mask[s]) mixed += weights[s] * z_impact[s * n + a];
            q[a] = s_blend * (w_t * z_task[a] + (1.0 - w_t) * mixed);
        }
    }
}

/* step 5: the final policy, Boltzmann of the blended Q (sl: the task policy itself) */
static int probs_step(const Batch *t, Work *w) {
    Py_ssize_t n = t->n;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        if (t->method == SL)
            memcpy(t->probs + b * n, w->policies + w->policy_at[b], n * sizeof(double));
        else
            boltzmann_inputs(t->q + b * n, 1, n, t->alpha[b], t->probs + b * n);
    }
    if (t->method == SL) return 0;
    if (ufunc_inplace(np_exp, t->probs, t->B * n) < 0) return -1;
    boltzmann_finish(t->probs, t->B, n);
    return 0;
}

/* float(np.power(float(n), h)) for every row's h, one call (eq. 9's |A|^H) */
static int power_step(Py_ssize_t n, const double *h, Py_ssize_t B, double *out) {
    PyObject *base = PyFloat_FromDouble((double)n);
    if (base == NULL) return -1;
    npy_intp dims[1] = {(npy_intp)B};
    PyObject *exponent = PyArray_SimpleNewFromData(1, dims, NPY_DOUBLE, (void *)h);
    PyObject *result = exponent ? PyObject_CallFunctionObjArgs(np_power, base, exponent, NULL)
                                : NULL;
    Py_DECREF(base);
    Py_XDECREF(exponent);
    if (result == NULL) return -1;
    int ok = PyArray_Check(result) && PyArray_SIZE((PyArrayObject *)result) == B &&
             PyArray_TYPE((PyArrayObject *)result) == NPY_DOUBLE &&
             PyArray_IS_C_CONTIGUOUS((PyArrayObject *)result);
    if (ok) memcpy(out, PyArray_DATA((PyArrayObject *)result), B * sizeof(double));
    Py_DECREF(result);
    if (!ok) PyErr_SetString(PyExc_RuntimeError, "np.power: expected float64 values");
    return ok ? 0 : -1;
}

/* the whole blend of a batch; 0, or -1 with a Python error set */
static int blend_batch(const Batch *t) {
    Py_ssize_t B = t->B, P = t->P, n = t->n, pairs = 0;
    Py_ssize_t *counts = PyMem_Malloc(3 * (B + 1) * sizeof(Py_ssize_t));
    if (counts == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    Work w = {counts, counts + B + 1, counts + 2 * (B + 1)};
    Py_ssize_t vectors = 0;
    for (Py_ssize_t b = 0; b < B; b++) {
        w.active[b] = 0;
        for (Py_ssize_t s = 0; s < P; s++) w.active[b] += t->mask[b * P + s] != 0;
        vectors += t->method == AAIL ? w.active[b] + 1 : 1;
        pairs += w.active[b];
    }
    if (t->method != AAIL) pairs = 0;
    /* policies (vectors n), p_once, p_twice (2 B n), logs (2 B n), h_eq9 + power (2 B),
       num, ratio (4 pairs n), z ((P + 1) n), scales (P) */
    Py_ssize_t size = vectors * n + 4 * B * n + 2 * B + 4 * pairs * n + (P + 1) * n + P + 1;
    double *memory = PyMem_Malloc(size * sizeof(double));
    int status = -1;
    if (memory == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    w.policies = memory;
    w.p_once = w.policies + vectors * n;
    w.p_twice = w.p_once + B * n;
    w.logs = w.p_twice + B * n;
    w.h_eq9 = w.logs + 2 * B * n;
    double *power = w.h_eq9 + B;
    w.num = power + B;
    w.ratio = w.num + 2 * pairs * n;
    w.z = w.ratio + 2 * pairs * n;
    w.scales = w.z + (P + 1) * n;
    if (policies_step(t, &w) < 0 || entropy_step(t, &w) < 0) goto done;
    if (t->method == AAIL && (power_step(n, w.h_eq9, B, power) < 0 || js_step(t, &w) < 0))
        goto done;
    blend_step(t, &w, power);
    status = probs_step(t, &w);
done:
    PyMem_Free(memory);
    PyMem_Free(counts);
    return status;
}

/* ---- Python objects in and out ------------------------------------------------------------ */

static int read_vector(PyObject *obj, Py_ssize_t n, double *out, const char *what) {
    PyObject *seq = PySequence_Fast(obj, what);
    if (seq == NULL) return -1;
    if (PySequence_Fast_GET_SIZE(seq) != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values", what, n);
        Py_DECREF(seq);
        return -1;
    }
    PyObject **items = PySequence_Fast_ITEMS(seq);
    for (Py_ssize_t i = 0; i < n; i++) {
        out[i] = PyFloat_AsDouble(items[i]);
        if (out[i] == -1.0 && PyErr_Occurred()) {
            Py_DECREF(seq);
            return -1;
        }
    }
    Py_DECREF(seq);
    return 0;
}

static PyObject *float_list(const double *x, Py_ssize_t n) {
    PyObject *list = PyList_New(n);
    if (list == NULL) return NULL;
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *value = PyFloat_FromDouble(x[i]);
        if (value == NULL) {
            Py_DECREF(list);
            return NULL;
        }
        PyList_SET_ITEM(list, i, value);
    }
    return list;
}

static int method_code(const char *method) {
    if (strcmp(method, "sl") == 0) return SL;
    if (strcmp(method, "nail") == 0) return NAIL;
    if (strcmp(method, "aail") == 0) return AAIL;
    PyErr_Format(PyExc_ValueError, "method: expected sl, nail or aail, got %s", method);
    return -1;
}

/* blend_row(method, q_task_A, q_impact_PA, alpha, mask_P, normalise) -> RowBlend of lists */
static PyObject *blend_row(PyObject *self, PyObject *args) {
    const char *method_name;
    PyObject *q_task_obj, *q_impact_obj, *mask_obj;
    double alpha;
    int normalise;
    if (!PyArg_ParseTuple(args, "sOOdOp", &method_name, &q_task_obj, &q_impact_obj, &alpha,
                          &mask_obj, &normalise))
        return NULL;
    int method = method_code(method_name);
    Py_ssize_t n = PySequence_Size(q_task_obj), P = PySequence_Size(q_impact_obj);
    if (method < 0 || n < 0 || P < 0) return NULL;
    if (n < 1) {
        PyErr_SetString(PyExc_ValueError, "q_task_A: expected at least one action");
        return NULL;
    }
    /* inputs n + P n, outputs 3 n + P + 2, the mask P bytes */
    double *memory = PyMem_Malloc((n + P * n + 3 * n + P + 2) * sizeof(double) + P + 1);
    if (memory == NULL) return PyErr_NoMemory();
    double *q_impact = memory + n, *q = q_impact + P * n, *probs = q + n;
    double *partner_weights = probs + n, *entropy = partner_weights + P, *weight = entropy + 1;
    char *mask = (char *)(weight + 1);
    Batch t = {1, P, n, method, normalise, memory, q_impact, &alpha, mask,
               q, probs, entropy, weight, partner_weights};
    PyObject *result = NULL;
    if (read_vector(q_task_obj, n, memory, "q_task_A") < 0) goto done;
    for (Py_ssize_t s = 0; s < P; s++) {
        mask[s] = 1;
        if (mask_obj != Py_None) {
            PyObject *flag = PySequence_GetItem(mask_obj, s);
            if (flag == NULL) goto done;
            int on = PyObject_IsTrue(flag);
            Py_DECREF(flag);
            if (on < 0) goto done;
            mask[s] = (char)on;
        }
        if (!mask[s]) continue; /* masked slots are never read */
        PyObject *vector = PySequence_GetItem(q_impact_obj, s);
        if (vector == NULL) goto done;
        int failed = read_vector(vector, n, q_impact + s * n, "q_impact_PA[i]");
        Py_DECREF(vector);
        if (failed < 0) goto done;
    }
    if (blend_batch(&t) < 0) goto done;
    PyObject *q_list = float_list(q, n), *p_list = float_list(probs, n);
    PyObject *w_list = float_list(partner_weights, P);
    if (q_list && p_list && w_list)
        result = PyObject_CallFunction(row_blend_type, "OOddO", q_list, p_list, entropy[0],
                                       weight[0], w_list);
    Py_XDECREF(q_list);
    Py_XDECREF(p_list);
    Py_XDECREF(w_list);
done:
    PyMem_Free(memory);
    return result;
}

static PyArrayObject *float64_array(PyObject *obj, int ndim, const char *what) {
    PyArrayObject *array = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, ndim, ndim,
                                                            NPY_ARRAY_IN_ARRAY);
    if (array == NULL) PyErr_Format(PyExc_ValueError, "%s: expected a %d-d float array", what, ndim);
    return array;
}

/* blend_rows(method, q_task_BA, q_impact_BPA, alpha_B, mask_BP, normalise)
   -> (q_BA, probs_BA, task_entropy_B, task_weight_B, partner_weights_BP), float64 arrays */
static PyObject *blend_rows(PyObject *self, PyObject *args) {
    const char *method_name;
    PyObject *objs[4];
    int normalise;
    if (!PyArg_ParseTuple(args, "sOOOOp", &method_name, &objs[0], &objs[1], &objs[2], &objs[3],
                          &normalise))
        return NULL;
    int method = method_code(method_name);
    if (method < 0) return NULL;
    PyArrayObject *q_task = float64_array(objs[0], 2, "q_task_BA");
    PyArrayObject *q_impact = q_task ? float64_array(objs[1], 3, "q_impact_BPA") : NULL;
    PyArrayObject *alpha = q_impact ? float64_array(objs[2], 1, "alpha_B") : NULL;
    PyArrayObject *mask = alpha ? (PyArrayObject *)PyArray_FROMANY(objs[3], NPY_BOOL, 2, 2,
                                                                   NPY_ARRAY_IN_ARRAY)
                                : NULL;
    PyObject *out[5] = {NULL}, *result = NULL;
    if (mask == NULL) goto done;
    npy_intp B = PyArray_DIM(q_task, 0), n = PyArray_DIM(q_task, 1), P = PyArray_DIM(q_impact, 1);
    if (n < 1 || PyArray_DIM(q_impact, 0) != B || PyArray_DIM(q_impact, 2) != n ||
        PyArray_DIM(alpha, 0) != B || PyArray_DIM(mask, 0) != B || PyArray_DIM(mask, 1) != P) {
        PyErr_SetString(PyExc_ValueError,
                        "expected shapes (B, A), (B, P, A), (B,), (B, P) with A >= 1");
        goto done;
    }
    npy_intp shapes[5][2] = {{B, n}, {B, n}, {B, 0}, {B, 0}, {B, P}};
    for (int i = 0; i < 5; i++) {
        out[i] = PyArray_SimpleNew(i == 2 || i == 3 ? 1 : 2, shapes[i], NPY_DOUBLE);
        if (out[i] == NULL) goto done;
    }
    Batch t = {B, P, n, method, normalise,
               PyArray_DATA(q_task), PyArray_DATA(q_impact), PyArray_DATA(alpha),
               PyArray_DATA(mask)};
    double **outputs[5] = {&t.q, &t.probs, &t.entropy, &t.weight, &t.partner_weights};
    for (int i = 0; i < 5; i++) *outputs[i] = PyArray_DATA((PyArrayObject *)out[i]);
    if (B > 0 && blend_batch(&t) < 0) goto done;
    result = PyTuple_Pack(5, out[0], out[1], out[2], out[3], out[4]);
done:
    for (int i = 0; i < 5; i++) Py_XDECREF(out[i]);
    Py_XDECREF(q_task);
    Py_XDECREF(q_impact);
    Py_XDECREF(alpha);
    Py_XDECREF(mask);
    return result;
}

static PyObject *set_result_type(PyObject *self, PyObject *type) {
    Py_XSETREF(row_blend_type, Py_NewRef(type));
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"blend_row", blend_row, METH_VARARGS,
     "blend_row(method, q_task_A, q_impact_PA, alpha, mask_P, normalise) -> RowBlend"},
    {"blend_rows", blend_rows, METH_VARARGS,
     "blend_rows(method, q_task_BA, q_impact_BPA, alpha_B, mask_BP, normalise) -> 5 arrays"},
    {"set_result_type", set_result_type, METH_O, "the RowBlend class results are made with"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_blend_row", NULL, -1, methods};

PyMODINIT_FUNC PyInit__blend_row(void) {
    import_array();
    PyObject *numpy = PyImport_ImportModule("numpy");
    if (numpy == NULL) return NULL;
    np_exp = PyObject_GetAttrString(numpy, "exp");
    np_log = PyObject_GetAttrString(numpy, "log");
    np_log2 = PyObject_GetAttrString(numpy, "log2");
    np_power = PyObject_GetAttrString(numpy, "power");
    Py_DECREF(numpy);
    if (!np_exp || !np_log || !np_log2 || !np_power) return NULL;
    row_blend_type = Py_NewRef((PyObject *)&PyTuple_Type);
    return PyModule_Create(&module);
}
