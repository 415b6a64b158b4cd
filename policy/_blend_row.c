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

#define FLAT_STD_RTOL 1e-12 /* blend_fast.FLAT_STD_RTOL */
#define PAIRWISE_BLOCK 128  /* numpy's PW_BLOCKSIZE */

static PyObject *np_exp, *np_log, *np_log2, *np_power, *row_blend_type;

/* ---- sums in numpy's (and blend_fast's) order ------------------------------------------- */

static double sequential_sum(const double *x, Py_ssize_t n) {
    double total = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) total += x[i];
    return total;
}

static double pairwise_sum(const double *x, Py_ssize_t n) { /* blend_fast.np_sum */
    if (n < 8) return sequential_sum(x, n);
    if (n <= PAIRWISE_BLOCK) {
        double acc[8];
        memcpy(acc, x, sizeof acc);
        Py_ssize_t stop = n - n % 8;
        for (Py_ssize_t i = 8; i < stop; i += 8)
            for (int j = 0; j < 8; j++) acc[j] += x[i + j];
        double total = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
        for (Py_ssize_t i = stop; i < n; i++) total += x[i];
        return total;
    }
    Py_ssize_t half = n / 2;
    half -= half % 8;
    return pairwise_sum(x, half) + pairwise_sum(x + half, n - half);
}

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

/* ---- numpy's ufuncs, in place on a C buffer ----------------------------------------------- */

static int ufunc_inplace(PyObject *ufunc, double *data, Py_ssize_t n) {
    npy_intp dims[1] = {(npy_intp)n};
    PyObject *array = PyArray_SimpleNewFromData(1, dims, NPY_DOUBLE, data);
    if (array == NULL) return -1;
    PyObject *out = PyObject_CallFunctionObjArgs(ufunc, array, array, NULL);
    Py_DECREF(array);
    if (out == NULL) return -1;
    Py_DECREF(out);
    return 0;
}

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

/* float(np.power(float(n), np.array([h]))[0]): eq. 9's |A|^H with a scalar base */
static int power_of_count(Py_ssize_t n, double h, double *out) {
    PyObject *base = PyFloat_FromDouble((double)n);
    if (base == NULL) return -1;
    npy_intp dims[1] = {1};
    PyObject *exponent = PyArray_SimpleNewFromData(1, dims, NPY_DOUBLE, &h);
    if (exponent == NULL) {
        Py_DECREF(base);
        return -1;
    }
    PyObject *result = PyObject_CallFunctionObjArgs(np_power, base, exponent, NULL);
    Py_DECREF(base);
    Py_DECREF(exponent);
    if (result == NULL) return -1;
    int ok = PyArray_Check(result) && PyArray_SIZE((PyArrayObject *)result) == 1 &&
             PyArray_TYPE((PyArrayObject *)result) == NPY_DOUBLE;
    if (ok) *out = *(double *)PyArray_DATA((PyArrayObject *)result);
    Py_DECREF(result);
    if (!ok) PyErr_SetString(PyExc_RuntimeError, "np.power: expected one float64");
    return ok ? 0 : -1;
}

/* ---- the steps of blend_fast ------------------------------------------------------------- */

/* _boltzmann: eq. 2 for `count` vectors of n (rows of `q`), one numpy exp for all */
static int boltzmann(const double *q, Py_ssize_t count, Py_ssize_t n, double alpha, double *out) {
    for (Py_ssize_t v = 0; v < count; v++) {
        const double *row = q + v * n;
        double top = first_max(row, n);
        for (Py_ssize_t a = 0; a < n; a++) out[v * n + a] = (row[a] - top) / alpha;
    }
    if (ufunc_inplace(np_exp, out, count * n) < 0) return -1;
    for (Py_ssize_t v = 0; v < count; v++) {
        double *e = out + v * n;
        double total = vsum(e, n, n);
        for (Py_ssize_t a = 0; a < n; a++) e[a] = e[a] / total;
    }
    return 0;
}

/* _renormalised, into `out` (a copy when the sum is exactly 1) */
static void renormalised(const double *p, Py_ssize_t n, double *out) {
    double total = vsum(p, n, n);
    for (Py_ssize_t a = 0; a < n; a++) out[a] = total == 1.0 ? p[a] : p[a] / total;
}

/* _entropies of one policy: maths.normalized_entropy */
static int entropy_of(const double *p, Py_ssize_t n, double *scratch, double *out) {
    if (n == 1) {
        *out = 0.0;
        return 0;
    }
    for (Py_ssize_t a = 0; a < n; a++) scratch[a] = p[a] > 0 ? p[a] : 1.0;
    if (ufunc_inplace(np_log, scratch, n) < 0) return -1;
    for (Py_ssize_t a = 0; a < n; a++) scratch[a] = p[a] > 0 ? p[a] * scratch[a] : 0.0;
    double log_n;
    if (log_of_count(n, &log_n) < 0) return -1;
    double h = -vsum(scratch, n, n) / log_n;
    *out = py_min2(py_max2(h, 0.0), 1.0);
    return 0;
}

/* _js_distances: eq. 10 of p to each of `count` policies (rows of `qs`), one numpy log2.
 * scratch: 4 * count * n doubles. */
static int js_distances(const double *p, const double *qs, Py_ssize_t count, Py_ssize_t n,
                        double *scratch, double *out) {
    Py_ssize_t half = count * n;
    double *num = scratch, *den = scratch + 2 * half; /* num = p_rep + q_flat, den = m + m */
    for (Py_ssize_t i = 0; i < half; i++) {
        num[i] = p[i % n];
        num[half + i] = qs[i];
        double m = 0.5 * (num[i] + qs[i]);
        den[i] = m;
        den[half + i] = m;
    }
    int regular = first_min(num, 2 * half) > 0 && first_min(den, half) > 0;
    double *ratios = den; /* overwritten in place: den is not read again */
    for (Py_ssize_t i = 0; i < 2 * half; i++) {
        if (regular)
            ratios[i] = num[i] / den[i];
        else /* numpy: 1 where the numerator is 0 (the term is 0), inf where m underflowed */
            ratios[i] = num[i] > 0 ? (den[i] > 0 ? num[i] / den[i] : Py_HUGE_VAL) : 1.0;
    }
    if (ufunc_inplace(np_log2, ratios, 2 * half) < 0) return -1;
    for (Py_ssize_t i = 0; i < 2 * half; i++)
        ratios[i] = regular ? num[i] * ratios[i] : (num[i] > 0 ? num[i] * ratios[i] : 0.0);
    for (Py_ssize_t v = 0; v < count; v++) {
        double kl_p = vsum(ratios + v * n, n, n), kl_q = vsum(ratios + half + v * n, n, n);
        out[v] = sqrt(py_min2(py_max2(0.5 * kl_p + 0.5 * kl_q, 0.0), 1.0));
    }
    return 0;
}

/* _standardise: z into `z` and the scale; z = 0 and scale 0 when flat */
static double standardise(const double *q, Py_ssize_t n, double *z) {
    double magnitude = py_max2(first_max(q, n), -first_min(q, n));
    double divisor = magnitude > 0 ? magnitude : 1.0;
    for (Py_ssize_t a = 0; a < n; a++) z[a] = q[a] / divisor;
    double mean = vsum(z, n, n) / n;
    for (Py_ssize_t a = 0; a < n; a++) z[a] = z[a] - mean; /* deviations */
    double squares_sum = 0.0;
    if (n < 8) {
        for (Py_ssize_t a = 0; a < n; a++) squares_sum += z[a] * z[a];
    } else {
        double *squares = PyMem_Malloc(n * sizeof(double));
        if (squares == NULL) return -1.0; /* caller checks PyErr_Occurred */
        for (Py_ssize_t a = 0; a < n; a++) squares[a] = z[a] * z[a];
        squares_sum = pairwise_sum(squares, n);
        PyMem_Free(squares);
    }
    double std = sqrt(squares_sum / n);
    if (std <= FLAT_STD_RTOL) {
        for (Py_ssize_t a = 0; a < n; a++) z[a] = 0.0;
        return 0.0;
    }
    for (Py_ssize_t a = 0; a < n; a++) z[a] = z[a] / std;
    return std * magnitude;
}

/* ---- Python objects in and out ----------------------------------------------------------- */

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

static PyObject *row_blend(const double *q, const double *probs, Py_ssize_t n, double entropy,
                           double task_weight, const double *weights, Py_ssize_t n_slots) {
    PyObject *q_list = float_list(q, n), *p_list = float_list(probs, n);
    PyObject *w_list = float_list(weights, n_slots);
    PyObject *result = NULL;
    if (q_list && p_list && w_list)
        result = PyObject_CallFunction(row_blend_type, "OOddO", q_list, p_list, entropy,
                                       task_weight, w_list);
    Py_XDECREF(q_list);
    Py_XDECREF(p_list);
    Py_XDECREF(w_list);
    return result;
}

/* ---- blend_row ---------------------------------------------------------------------------- */

typedef struct {
    Py_ssize_t n, slots, active;
    double alpha;
    double *q_task, *q_impact; /* (n), (slots, n): masked rows are never read */
    int *mask;
    double *work; /* everything else */
} Row;

static PyObject *blend_sl_nail_aail(const char *method, Row *r, int normalise) {
    Py_ssize_t n = r->n, P = r->slots, k = r->active;
    /* work layout: policies (k+1)n | p_once n | p_twice n | impact pis kn | scratch 4kn+n |
       jsd k | weights P | scales P | z_task n | z (k)n | mixed n | q_blend n | probs n */
    double *policies = r->work, *p_once = policies + (k + 1) * n, *p_twice = p_once + n;
    double *pis = p_twice + n, *scratch = pis + k * n, *jsd = scratch + 4 * k * n + n;
    double *weights = jsd + k, *scales = weights + P, *z_task = scales + P;
    double *z_active = z_task + n, *mixed = z_active + k * n, *q_blend = mixed + n;
    double *probs = q_blend + n;
    int aail = strcmp(method, "aail") == 0, nail = strcmp(method, "nail") == 0;

    /* the Boltzmann policies of the task and (aail) of every active impact, one exp */
    double *stacked = scratch; /* rows: the task, then the active impacts */
    memcpy(stacked, r->q_task, n * sizeof(double));
    Py_ssize_t row = 1;
    if (aail)
        for (Py_ssize_t s = 0; s < P; s++)
            if (r->mask[s]) memcpy(stacked + n * row++, r->q_impact + s * n, n * sizeof(double));
    if (boltzmann(stacked, aail ? k + 1 : 1, n, r->alpha, policies) < 0) return NULL;
    renormalised(policies, n, p_once);
    double entropy;
    if (entropy_of(p_once, n, scratch, &entropy) < 0) return NULL;
    if (!aail && !nail) { /* sl */
        memset(weights, 0, P * sizeof(double));
        return row_blend(r->q_task, policies, n, entropy, 1.0, weights, P);
    }
    if (nail) { /* the raw mean of the task and the active impact Q-vectors (§4.2) */
        if (n == 1) { /* numpy then sums over the contiguous partner axis: pairwise */
            for (Py_ssize_t s = 0; s < P; s++) scales[s] = r->mask[s] ? r->q_impact[s * n] : 0.0;
            mixed[0] = pairwise_sum(scales, P);
        } else { /* numpy adds the partners' vectors one after the other */
            memset(mixed, 0, n * sizeof(double));
            for (Py_ssize_t s = 0; s < P; s++)
                if (r->mask[s])
                    for (Py_ssize_t a = 0; a < n; a++) mixed[a] = mixed[a] + r->q_impact[s * n + a];
        }
        for (Py_ssize_t a = 0; a < n; a++) q_blend[a] = (r->q_task[a] + mixed[a]) / (1.0 + k);
        for (Py_ssize_t s = 0; s < P; s++) weights[s] = r->mask[s] ? 1.0 / (k > 1 ? k : 1) : 0.0;
        if (boltzmann(q_blend, 1, n, r->alpha, probs) < 0) return NULL;
        return row_blend(q_blend, probs, n, entropy, 1.0 / (1.0 + k), weights, P);
    }

    /* aail: eq. 9's weight on the twice-renormalised policy, as maths.task_weight sees it */
    renormalised(p_once, n, p_twice);
    double h_eq9 = entropy; /* p_twice is p_once when p_once sums to exactly 1 */
    if (vsum(p_once, n, n) != 1.0 && entropy_of(p_twice, n, scratch, &h_eq9) < 0) return NULL;
    double power;
    if (power_of_count(n, h_eq9, &power) < 0) return NULL;
    double w_eq9 = n > 1 ? 1.0 - power / n : 1.0;
    for (Py_ssize_t v = 0; v < k; v++) renormalised(policies + (v + 1) * n, n, pis + v * n);
    if (k > 0 && js_distances(p_once, pis, k, n, scratch, jsd) < 0) return NULL;

    /* eqs. 8-10 given the JS distances (blend_fast._aail) */
    Py_ssize_t next = 0;
    for (Py_ssize_t s = 0; s < P; s++) weights[s] = r->mask[s] ? jsd[next++] : 0.0;
    double total = pairwise_sum(weights, P);
    for (Py_ssize_t s = 0; s < P; s++) {
        if (total > 0)
            weights[s] = weights[s] / total;
        else /* every impact policy equals the task policy: equal shares */
            weights[s] = r->mask[s] ? 1.0 / (k > 1 ? k : 1) : 0.0;
    }
    double w_t = k > 0 ? w_eq9 : 1.0; /* no partner: the task alone */
    if (!normalise) { /* eq. 8 on the raw Q-vectors (blend_fast._aail_raw) */
        for (Py_ssize_t a = 0; a < n; a++) {
            double acc = 0.0;
            for (Py_ssize_t s = 0; s < P; s++)
                if (r->mask[s]) acc += weights[s] * r->q_impact[s * n + a];
            q_blend[a] = w_t * r->q_task[a] + (1.0 - w_t) * acc;
        }
    } else {
        double s_task = standardise(r->q_task, n, z_task);
        if (s_task == -1.0 && PyErr_Occurred()) return NULL;
        Py_ssize_t v = 0;
        for (Py_ssize_t s = 0; s < P; s++) {
            scales[s] = 0.0; /* masked slots: z = 0 and scale 0 */
            if (r->mask[s]) {
                scales[s] = standardise(r->q_impact + s * n, n, z_active + v * n);
                if (scales[s] == -1.0 && PyErr_Occurred()) return NULL;
                v++;
            }
        }
        /* Σ_i ŵ_i z_i one action at a time, partners in order (numpy's einsum order) */
        for (Py_ssize_t a = 0; a < n; a++) {
            double acc = 0.0;
            Py_ssize_t u = 0;
            for (Py_ssize_t s = 0; s < P; s++)
                if (r->mask[s]) acc += weights[s] * z_active[u++ * n + a];
            mixed[a] = acc;
        }
        for (Py_ssize_t s = 0; s < P; s++) scales[s] = weights[s] * scales[s];
        double s_blend = w_t * s_task + (1.0 - w_t) * pairwise_sum(scales, P);
        for (Py_ssize_t a = 0; a < n; a++)
            q_blend[a] = s_blend * (w_t * z_task[a] + (1.0 - w_t) * mixed[a]);
    }
    if (boltzmann(q_blend, 1, n, r->alpha, probs) < 0) return NULL;
    return row_blend(q_blend, probs, n, entropy, w_t, weights, P);
}

static PyObject *blend_row(PyObject *self, PyObject *args) {
    const char *method;
    PyObject *q_task_obj, *q_impact_obj, *mask_obj;
    double alpha;
    int normalise;
    if (!PyArg_ParseTuple(args, "sOOdOp", &method, &q_task_obj, &q_impact_obj, &alpha, &mask_obj,
                          &normalise))
        return NULL;
    if (strcmp(method, "sl") && strcmp(method, "nail") && strcmp(method, "aail")) {
        PyErr_Format(PyExc_ValueError, "method: expected sl, nail or aail, got %s", method);
        return NULL;
    }
    Row r = {0};
    r.alpha = alpha;
    r.n = PySequence_Size(q_task_obj);
    r.slots = PySequence_Size(q_impact_obj);
    if (r.n < 0 || r.slots < 0) return NULL;
    if (r.n < 1) {
        PyErr_SetString(PyExc_ValueError, "q_task_A: expected at least one action");
        return NULL;
    }
    Py_ssize_t n = r.n, P = r.slots;
    /* the inputs (n + Pn) and every buffer of blend_sl_nail_aail (at most n(7P + 8) + 3P) */
    Py_ssize_t size = n * (8 * P + 10) + 3 * P + 8;
    double *memory = PyMem_Malloc(size * sizeof(double) + P * sizeof(int));
    if (memory == NULL) return PyErr_NoMemory();
    r.q_task = memory;
    r.q_impact = memory + n;
    r.work = r.q_impact + P * n;
    r.mask = (int *)(memory + size);
    PyObject *result = NULL;
    if (read_vector(q_task_obj, n, r.q_task, "q_task_A") < 0) goto done;
    for (Py_ssize_t s = 0; s < P; s++) {
        r.mask[s] = 1;
        if (mask_obj != Py_None) {
            PyObject *flag = PySequence_GetItem(mask_obj, s);
            if (flag == NULL) goto done;
            r.mask[s] = PyObject_IsTrue(flag);
            Py_DECREF(flag);
            if (r.mask[s] < 0) goto done;
        }
        r.active += r.mask[s];
    }
    for (Py_ssize_t s = 0; s < P; s++) {
        if (!r.mask[s]) continue; /* masked slots are never read */
        PyObject *vector = PySequence_GetItem(q_impact_obj, s);
        if (vector == NULL) goto done;
        int failed = read_vector(vector, n, r.q_impact + s * n, "q_impact_PA[i]");
        Py_DECREF(vector);
        if (failed < 0) goto done;
    }
    result = blend_sl_nail_aail(method, &r, normalise);
done:
    PyMem_Free(memory);
    return result;
}

static PyObject *set_result_type(PyObject *self, PyObject *type) {
    Py_XSETREF(row_blend_type, Py_NewRef(type));
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"blend_row", blend_row, METH_VARARGS,
     "blend_row(method, q_task_A, q_impact_PA, alpha, mask_P, normalise) -> RowBlend"},
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
