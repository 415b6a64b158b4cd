/* policy._belief_row: a session's belief step in C: the update of
 * `policy.belief.PreparedUpdate` (its all-finite case) and `policy.belief_views.belief_views`
 * (its whole-belief, all-positive case), for E rows of G goals, and the goal likelihoods' log
 * softmax table (services.engine.goal_inference), and the expected impact Q of goal
 * distributions (`mix_goals`, services.engine.engine._impact_q).
 *
 * Why C: with G = 35 goals and a few partners the update and the views are ~25 small numpy
 * calls and Python loops over 35 floats; here they are C loops over the rows.
 *
 * The numpy code (policy.belief, policy.belief_views, goal_inference) is the reference; the
 * steps below follow it, with plain sums and libm's exp, log and log1p, so the results differ
 * by rounding: tests/policy/test_belief_compiled.py holds them to it within 1e-12. Rows outside
 * the cases above (a non-finite likelihood or update, a zero probability) are the numpy
 * code's: `update_rows` answers None, `view_rows` None for such a row, and the Python wrappers
 * (policy.belief, policy.belief_views) then take their numpy paths.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#define MAX_TOP 64 /* top goals a view lists at most (the sessions list 3) */

static double sum(const double *x, Py_ssize_t n) {
    double total = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) total += x[i];
    return total;
}

/* numpy's logaddexp(x, c): log(exp(x) + exp(c)) without overflow */
static double logaddexp(double x, double c) {
    if (x == c) return x + M_LN2;
    double top = x > c ? x : c, gap = x > c ? c - x : x - c;
    return top + log1p(exp(gap));
}

/* a C-contiguous float64 (E, G) array, or NULL with an exception naming `what` */
static PyArrayObject *rows_array(PyObject *obj, const char *what) {
    if (!PyArray_Check(obj) || PyArray_TYPE((PyArrayObject *)obj) != NPY_DOUBLE ||
        !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)obj) || PyArray_NDIM((PyArrayObject *)obj) != 2 ||
        PyArray_DIM((PyArrayObject *)obj, 1) < 1) {
        PyErr_Format(PyExc_ValueError, "%s: expected a C-contiguous float64 array (E, G), G >= 1",
                     what);
        return NULL;
    }
    return (PyArrayObject *)obj;
}

/* update_rows(log_b, lik, pull, lam, floor_scale, floor_log) -> (E, G) float64, or None
 *
 * PreparedUpdate's arithmetic (policy.belief._updated, all-finite case), per row:
 *   x = lam * log_b + lik (+ pull); norm = top + log(sum(exp(x - top))), top = max(x);
 *   z = x - norm; with a floor: logaddexp(floor_scale + z, floor_log)
 * where floor_scale = log1p(-G floor) and floor_log = log(floor) (Python's, passed in;
 * floor_log None: no floor). None when a likelihood or an x is not finite (the masked path). */
static PyObject *update_rows(PyObject *self, PyObject *args) {
    PyObject *b_obj, *lik_obj, *pull_obj, *floor_log_obj;
    double lam, floor_scale;
    if (!PyArg_ParseTuple(args, "OOOddO", &b_obj, &lik_obj, &pull_obj, &lam, &floor_scale,
                          &floor_log_obj))
        return NULL;
    PyArrayObject *b = rows_array(b_obj, "log_belief"), *lik = b ? rows_array(lik_obj, "lik") : NULL;
    PyArrayObject *pull = NULL;
    if (lik == NULL) return NULL;
    if (pull_obj != Py_None && (pull = rows_array(pull_obj, "pull")) == NULL) return NULL;
    Py_ssize_t E = PyArray_DIM(b, 0), G = PyArray_DIM(b, 1);
    if (PyArray_DIM(lik, 0) != E || PyArray_DIM(lik, 1) != G ||
        (pull && (PyArray_DIM(pull, 0) != E || PyArray_DIM(pull, 1) != G))) {
        PyErr_SetString(PyExc_ValueError, "lik, pull: expected the shape of log_belief");
        return NULL;
    }
    double floor_log = 0.0;
    int floored = floor_log_obj != Py_None;
    if (floored && (floor_log = PyFloat_AsDouble(floor_log_obj)) == -1.0 && PyErr_Occurred())
        return NULL;
    const double *lb = PyArray_DATA(b), *lk = PyArray_DATA(lik);
    const double *pl = pull ? PyArray_DATA(pull) : NULL;
    for (Py_ssize_t i = 0; i < E * G; i++)
        if (!isfinite(lk[i])) Py_RETURN_NONE;
    npy_intp dims[2] = {E, G};
    PyObject *out = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    double *work = out ? PyMem_Malloc(((size_t)E * G + 2 * E) * sizeof(double)) : NULL;
    if (work == NULL) {
        Py_XDECREF(out);
        return PyErr_Occurred() ? NULL : PyErr_NoMemory();
    }
    double *x = PyArray_DATA((PyArrayObject *)out), *shifted = work, *top_of = work + E * G;
    double *sums = top_of + E;
    for (Py_ssize_t i = 0; i < E * G; i++) {
        double v = lam * lb[i] + lk[i];
        x[i] = pl ? v + pl[i] : v;
        if (!isfinite(x[i])) {
            PyMem_Free(work);
            Py_DECREF(out);
            Py_RETURN_NONE;
        }
    }
    for (Py_ssize_t e = 0; e < E; e++) {
        const double *row = x + e * G;
        double top = row[0];
        for (Py_ssize_t g = 1; g < G; g++)
            if (row[g] > top) top = row[g];
        top_of[e] = top;
        for (Py_ssize_t g = 0; g < G; g++) shifted[e * G + g] = row[g] - top;
    }
    for (Py_ssize_t i = 0; i < E * G; i++) shifted[i] = exp(shifted[i]);
    for (Py_ssize_t e = 0; e < E; e++) sums[e] = log(sum(shifted + e * G, G));
    for (Py_ssize_t e = 0; e < E; e++) {
        double n = top_of[e] + sums[e];
        for (Py_ssize_t g = 0; g < G; g++) {
            double z = x[e * G + g] - n;
            x[e * G + g] = floored ? logaddexp(floor_scale + z, floor_log) : z;
        }
    }
    PyMem_Free(work);
    return out;
}

/* view_rows(log_b, k) -> [(probs, blend_probs, top_indices, entropy), ...]
 *
 * belief_views' numbers for rows whose probabilities are all > 0, blended whole: b = exp(log_b)
 * (probs, a list), blend_probs = [q / sum(probs)], the k most probable goals (stable order of
 * -log b), entropy = max(0, -sum(b log b)). Rows with a zero probability: None in their place
 * (the caller takes the Python path for them). */
static PyObject *view_rows(PyObject *self, PyObject *args) {
    PyObject *b_obj;
    Py_ssize_t k;
    if (!PyArg_ParseTuple(args, "On", &b_obj, &k)) return NULL;
    PyArrayObject *b = rows_array(b_obj, "log_belief");
    if (b == NULL) return NULL;
    if (k < 1 || k > MAX_TOP) {
        PyErr_Format(PyExc_ValueError, "k: expected 1..%d", MAX_TOP);
        return NULL;
    }
    Py_ssize_t E = PyArray_DIM(b, 0), G = PyArray_DIM(b, 1), top_k = k < G ? k : G;
    const double *lb = PyArray_DATA(b);
    double *probs = PyMem_Malloc(((size_t)E * G * 2) * sizeof(double));
    PyObject *result = probs ? PyList_New(E) : NULL;
    if (result == NULL) {
        PyMem_Free(probs);
        return PyErr_Occurred() ? NULL : PyErr_NoMemory();
    }
    double *terms = probs + E * G;
    memcpy(probs, lb, (size_t)E * G * sizeof(double));
    for (Py_ssize_t i = 0; i < E * G; i++) probs[i] = exp(probs[i]);
    for (Py_ssize_t e = 0; e < E; e++) {
        const double *p = probs + e * G, *row = lb + e * G;
        int positive = 1;
        for (Py_ssize_t g = 0; g < G; g++) {
            if (!(p[g] > 0)) positive = 0;
            terms[e * G + g] = p[g] * row[g];
        }
        if (!positive) {
            PyList_SET_ITEM(result, e, Py_NewRef(Py_None));
            continue;
        }
        double h = -sum(terms + e * G, G);
        PyObject *plist = PyList_New(G), *top = PyList_New(top_k), *item = NULL;
        if (plist == NULL || top == NULL) goto row_fail;
        for (Py_ssize_t g = 0; g < G; g++) {
            PyObject *v = PyFloat_FromDouble(p[g]);
            if (v == NULL) goto row_fail;
            PyList_SET_ITEM(plist, g, v);
        }
        /* the stable descending order's first k: repeatedly the largest log b not yet taken,
         * the lowest index among equals (what argsort(-log_b, kind="stable") puts first) */
        Py_ssize_t chosen[MAX_TOP];
        for (Py_ssize_t j = 0; j < top_k; j++) {
            Py_ssize_t best = -1;
            for (Py_ssize_t g = 0; g < G; g++) {
                int taken = 0;
                for (Py_ssize_t i = 0; i < j; i++) taken |= chosen[i] == g;
                if (!taken && (best < 0 || -row[g] < -row[best])) best = g;
            }
            chosen[j] = best;
            PyObject *index = PyLong_FromSsize_t(best);
            if (index == NULL) goto row_fail;
            PyList_SET_ITEM(top, j, index);
        }
        double total = sum(p, G);
        PyObject *blend = PyList_New(G);
        if (blend == NULL) goto row_fail;
        for (Py_ssize_t g = 0; g < G; g++) {
            PyObject *v = PyFloat_FromDouble(p[g] / total);
            if (v == NULL) {
                Py_DECREF(blend);
                goto row_fail;
            }
            PyList_SET_ITEM(blend, g, v);
        }
        item = Py_BuildValue("(NNNd)", plist, blend, top, h > 0.0 ? h : 0.0); /* max(0.0, h) */
        if (item == NULL) goto fail;  /* the references went to Py_BuildValue */
        PyList_SET_ITEM(result, e, item);
        continue;
    row_fail:
        Py_XDECREF(plist);
        Py_XDECREF(top);
        goto fail;
    }
    PyMem_Free(probs);
    return result;
fail:
    PyMem_Free(probs);
    Py_DECREF(result);
    return NULL;
}

/* log_softmax_table(q_GPA, alpha) -> (G, P, A) float64
 *
 * log softmax(Q / alpha_g) of every row, as services.engine.goal_inference computes its
 * likelihood table (`_scaled`, then z - log_norm): z = (float64(q) - max q) / alpha_g, then
 * z - log(sum(exp(z))). `alpha` a float
 * or G float64 values; q finite (the caller checks). */
static PyObject *log_softmax_table(PyObject *self, PyObject *args) {
    PyObject *q_obj, *alpha_obj;
    if (!PyArg_ParseTuple(args, "OO", &q_obj, &alpha_obj)) return NULL;
    if (!PyArray_Check(q_obj) || PyArray_TYPE((PyArrayObject *)q_obj) != NPY_FLOAT32 ||
        !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)q_obj) || PyArray_NDIM((PyArrayObject *)q_obj) != 3 ||
        PyArray_DIM((PyArrayObject *)q_obj, 2) < 1) {
        PyErr_SetString(PyExc_ValueError, "q_GPA: expected a C-contiguous float32 array (G, P, A)");
        return NULL;
    }
    PyArrayObject *q = (PyArrayObject *)q_obj;
    Py_ssize_t G = PyArray_DIM(q, 0), P = PyArray_DIM(q, 1), A = PyArray_DIM(q, 2);
    const double *alphas = NULL;
    double alpha = 0.0;
    if (PyArray_Check(alpha_obj)) {
        PyArrayObject *a = (PyArrayObject *)alpha_obj;
        if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(a) || PyArray_SIZE(a) != G) {
            PyErr_SetString(PyExc_ValueError, "alpha: expected a float or G float64 values");
            return NULL;
        }
        alphas = PyArray_DATA(a);
    } else if ((alpha = PyFloat_AsDouble(alpha_obj)) == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    npy_intp dims[3] = {G, P, A};
    PyObject *out = PyArray_SimpleNew(3, dims, NPY_DOUBLE);
    double *work = out ? PyMem_Malloc(((size_t)G * P * A + (size_t)G * P) * sizeof(double)) : NULL;
    if (work == NULL) {
        Py_XDECREF(out);
        return PyErr_Occurred() ? NULL : PyErr_NoMemory();
    }
    const float *qd = PyArray_DATA(q);
    double *z = PyArray_DATA((PyArrayObject *)out), *e = work, *norm = work + (size_t)G * P * A;
    for (Py_ssize_t g = 0; g < G; g++) {
        double a = alphas ? alphas[g] : alpha;
        for (Py_ssize_t p = 0; p < P; p++) {
            Py_ssize_t at = (g * P + p) * A;
            double top = (double)qd[at];
            for (Py_ssize_t i = 1; i < A; i++)
                if ((double)qd[at + i] > top) top = (double)qd[at + i];
            for (Py_ssize_t i = 0; i < A; i++) z[at + i] = e[at + i] = ((double)qd[at + i] - top) / a;
        }
    }
    for (Py_ssize_t i = 0; i < G * P * A; i++) e[i] = exp(e[i]);
    for (Py_ssize_t r = 0; r < G * P; r++) norm[r] = log(sum(e + r * A, A));
    for (Py_ssize_t r = 0; r < G * P; r++)
        for (Py_ssize_t i = 0; i < A; i++) z[r * A + i] -= norm[r];
    PyMem_Free(work);
    return out;
}

/* mix_goals(q_RA, units_PG, probs, batch) -> (B, P, A) float64
 *
 * The expected impact Q of P goal distributions over G goals each (paper §3.2), as
 * services.engine.engine._impact_q computes it with numpy's einsum: out[b, p, a] =
 * sum over g, in order, of probs[p][g] * q[units[p, g] * B + b, a], in float64. `q_RA` is the
 * impact members' float32 rows (unit u's B rows at u * B), `units_PG` intp, `probs` P
 * sequences of G numbers. One C loop instead of a gather, a cast and an einsum. */
static PyObject *mix_goals(PyObject *self, PyObject *args) {
    PyObject *q_obj, *units_obj, *probs_obj;
    Py_ssize_t B;
    if (!PyArg_ParseTuple(args, "OOOn", &q_obj, &units_obj, &probs_obj, &B)) return NULL;
    if (!PyArray_Check(q_obj) || PyArray_TYPE((PyArrayObject *)q_obj) != NPY_FLOAT32 ||
        !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)q_obj) || PyArray_NDIM((PyArrayObject *)q_obj) != 2) {
        PyErr_SetString(PyExc_ValueError, "q_RA: expected a C-contiguous float32 array (R, A)");
        return NULL;
    }
    if (!PyArray_Check(units_obj) || PyArray_TYPE((PyArrayObject *)units_obj) != NPY_INTP ||
        !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)units_obj) ||
        PyArray_NDIM((PyArrayObject *)units_obj) != 2) {
        PyErr_SetString(PyExc_ValueError, "units_PG: expected a C-contiguous intp array (P, G)");
        return NULL;
    }
    PyArrayObject *q = (PyArrayObject *)q_obj, *units = (PyArrayObject *)units_obj;
    Py_ssize_t R = PyArray_DIM(q, 0), A = PyArray_DIM(q, 1);
    Py_ssize_t P = PyArray_DIM(units, 0), G = PyArray_DIM(units, 1);
    if (B < 1) {
        PyErr_SetString(PyExc_ValueError, "batch: expected >= 1");
        return NULL;
    }
    PyObject *rows = PySequence_Fast(probs_obj, "probs: expected a sequence of P sequences");
    if (rows == NULL) return NULL;
    if (PySequence_Fast_GET_SIZE(rows) != P) {
        Py_DECREF(rows);
        PyErr_SetString(PyExc_ValueError, "probs: expected one sequence per row of units_PG");
        return NULL;
    }
    const npy_intp *unit = PyArray_DATA(units);
    for (Py_ssize_t i = 0; i < P * G; i++) {
        if (unit[i] < 0 || (unit[i] + 1) * B > R) {
            Py_DECREF(rows);
            PyErr_SetString(PyExc_ValueError, "units_PG: a unit outside q_RA's rows");
            return NULL;
        }
    }
    npy_intp dims[3] = {B, P, A};
    PyObject *out = PyArray_ZEROS(3, dims, NPY_DOUBLE, 0);
    if (out == NULL) {
        Py_DECREF(rows);
        return NULL;
    }
    const float *qd = PyArray_DATA(q);
    double *o = PyArray_DATA((PyArrayObject *)out);
    for (Py_ssize_t p = 0; p < P; p++) {
        PyObject *row = PySequence_Fast(PySequence_Fast_GET_ITEM(rows, p),
                                        "probs: expected a sequence of P sequences");
        if (row == NULL || PySequence_Fast_GET_SIZE(row) != G) {
            if (row != NULL)
                PyErr_SetString(PyExc_ValueError, "probs: expected G numbers per partner");
            Py_XDECREF(row);
            Py_DECREF(rows);
            Py_DECREF(out);
            return NULL;
        }
        for (Py_ssize_t g = 0; g < G; g++) {
            double w = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(row, g));
            if (w == -1.0 && PyErr_Occurred()) {
                Py_DECREF(row);
                Py_DECREF(rows);
                Py_DECREF(out);
                return NULL;
            }
            const float *src = qd + unit[p * G + g] * B * A;
            for (Py_ssize_t b = 0; b < B; b++)
                for (Py_ssize_t a = 0; a < A; a++)
                    o[(b * P + p) * A + a] += w * (double)src[b * A + a];
        }
        Py_DECREF(row);
    }
    Py_DECREF(rows);
    return out;
}

static PyMethodDef methods[] = {
    {"mix_goals", mix_goals, METH_VARARGS,
     "mix_goals(q_RA, units_PG, probs, batch) -> (B, P, A) float64 expected impact Q"},
    {"log_softmax_table", log_softmax_table, METH_VARARGS,
     "log_softmax_table(q_GPA, alpha) -> (G, P, A) float64 log softmax(q / alpha_g)"},
    {"update_rows", update_rows, METH_VARARGS,
     "update_rows(log_b, lik, pull, lam, floor_scale, floor_log) -> (E, G) array or None"},
    {"view_rows", view_rows, METH_VARARGS,
     "view_rows(log_b, k) -> per row (probs, blend_probs, top_indices, entropy) or None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_belief_row", NULL, -1, methods};

PyMODINIT_FUNC PyInit__belief_row(void) {
    import_array();
    return PyModule_Create(&module);
}
