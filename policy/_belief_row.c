/* policy._belief_row: a session's belief step in C, with numpy's bits: the update of
 * `policy.belief.PreparedUpdate` (its all-finite case) and `policy.belief_views.belief_views`
 * (its whole-belief, all-positive case), for E rows of G goals; the goal likelihoods' log
 * softmax table (services.engine.goal_inference) and the expected impact Q of a goal
 * distribution (services.engine.fastpath).
 *
 * Why C: with G = 35 the update and the views are ~25 small numpy calls and a few Python loops
 * over 35 floats, ~45 µs of a REST session step; here they are 4 numpy calls and C loops.
 *
 * How the bits stay numpy's (tests/policy/test_belief_row_compiled.py compares them):
 * - + - * and max are IEEE operations in numpy and C alike; the build turns off contraction
 *   into fused multiply-adds (-ffp-contract=off, setup.py);
 * - exp, log and logaddexp are numpy's ufuncs, called on C buffers (numpy's SIMD versions can
 *   differ from libm's in the last bit); a ufunc's result for one element does not depend on
 *   the others, so each is called once for all rows;
 * - sums over goals are numpy's pairwise sums (_numpy_order.h); the blend's normaliser is
 *   Python's math.fsum, called as belief_views calls it;
 * - the top goals are numpy's stable argsort of -log b: descending, ties by goal index.
 * Rows outside those cases (a non-finite likelihood or update, a zero probability) are the
 * Python code's: `update_rows` answers None, `view_rows` None for such a row, and the Python
 * wrappers (policy.belief, policy.belief_views) then take their numpy paths.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include "_numpy_order.h"

#define MAX_TOP 64 /* top goals a view lists at most (the sessions list 3) */

static PyObject *np_exp, *np_log, *np_logaddexp, *math_fsum;

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

/* np.logaddexp(x, c, out=x) on a C buffer */
static int logaddexp_inplace(double *data, Py_ssize_t n, double c) {
    npy_intp dims[1] = {(npy_intp)n};
    PyObject *array = PyArray_SimpleNewFromData(1, dims, NPY_DOUBLE, data);
    PyObject *scalar = array ? PyFloat_FromDouble(c) : NULL;
    PyObject *out = scalar ? PyObject_CallFunctionObjArgs(np_logaddexp, array, scalar, array, NULL)
                           : NULL;
    Py_XDECREF(array);
    Py_XDECREF(scalar);
    if (out == NULL) return -1;
    Py_DECREF(out);
    return 0;
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
    if (ufunc_inplace(np_exp, shifted, E * G) < 0) goto fail;
    for (Py_ssize_t e = 0; e < E; e++) sums[e] = pairwise_sum(shifted + e * G, G);
    if (ufunc_inplace(np_log, sums, E) < 0) goto fail;
    for (Py_ssize_t e = 0; e < E; e++) {
        double n = top_of[e] + sums[e];
        for (Py_ssize_t g = 0; g < G; g++) {
            double z = x[e * G + g] - n;
            x[e * G + g] = floored ? floor_scale + z : z;
        }
    }
    if (floored && logaddexp_inplace(x, E * G, floor_log) < 0) goto fail;
    PyMem_Free(work);
    return out;
fail:
    PyMem_Free(work);
    Py_DECREF(out);
    return NULL;
}

/* view_rows(log_b, k) -> [(probs, blend_probs, top_indices, entropy), ...]
 *
 * belief_views' numbers for rows whose probabilities are all > 0, blended whole: b = exp(log_b)
 * (probs, a list), blend_probs = [q / fsum(probs)], the k most probable goals (stable order of
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
    if (ufunc_inplace(np_exp, probs, E * G) < 0) goto fail;
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
        double h = -pairwise_sum(terms + e * G, G);
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
        PyObject *total_obj = PyObject_CallOneArg(math_fsum, plist);
        if (total_obj == NULL) goto row_fail;
        double total = PyFloat_AsDouble(total_obj);
        Py_DECREF(total_obj);
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
 * z - log(sum(exp(z))) with numpy's exp and log and the pairwise sum over A. `alpha` a float
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
    if (ufunc_inplace(np_exp, e, G * P * A) < 0) goto fail;
    for (Py_ssize_t r = 0; r < G * P; r++) norm[r] = pairwise_sum(e + r * A, A);
    if (ufunc_inplace(np_log, norm, G * P) < 0) goto fail;
    for (Py_ssize_t r = 0; r < G * P; r++)
        for (Py_ssize_t i = 0; i < A; i++) z[r * A + i] -= norm[r];
    PyMem_Free(work);
    return out;
fail:
    PyMem_Free(work);
    Py_DECREF(out);
    return NULL;
}

/* mix_rows(probs, q_RA, rows) -> list of A floats
 *
 * A goal distribution's expected Q (the engine's single-row mix, services.engine.fastpath):
 * sum over j of probs[j] * float64(q[rows[j]]), added in order (np.add.accumulate's order). */
static PyObject *mix_rows(PyObject *self, PyObject *args) {
    PyObject *probs_obj, *q_obj, *rows_obj;
    if (!PyArg_ParseTuple(args, "OOO", &probs_obj, &q_obj, &rows_obj)) return NULL;
    if (!PyArray_Check(q_obj) || PyArray_TYPE((PyArrayObject *)q_obj) != NPY_FLOAT32 ||
        !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)q_obj) || PyArray_NDIM((PyArrayObject *)q_obj) != 2) {
        PyErr_SetString(PyExc_ValueError, "q_RA: expected a C-contiguous float32 array (R, A)");
        return NULL;
    }
    PyArrayObject *q = (PyArrayObject *)q_obj;
    Py_ssize_t R = PyArray_DIM(q, 0), A = PyArray_DIM(q, 1);
    PyObject *probs = PySequence_Fast(probs_obj, "probs: expected a sequence of floats");
    PyObject *rows = probs ? PySequence_Fast(rows_obj, "rows: expected a sequence of ints") : NULL;
    double *acc = rows ? PyMem_Calloc((size_t)A + 1, sizeof(double)) : NULL;
    PyObject *result = NULL;
    if (acc == NULL) goto done;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(probs);
    if (n < 1 || PySequence_Fast_GET_SIZE(rows) != n) {
        PyErr_SetString(PyExc_ValueError, "probs, rows: expected one row per probability (>= 1)");
        goto done;
    }
    const float *qd = PyArray_DATA(q);
    for (Py_ssize_t j = 0; j < n; j++) {
        double p = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(probs, j));
        Py_ssize_t row = PyLong_AsSsize_t(PySequence_Fast_GET_ITEM(rows, j));
        if (PyErr_Occurred()) goto done;
        if (row < 0 || row >= R) {
            PyErr_Format(PyExc_ValueError, "rows[%zd]: %zd is not a row of q_RA", j, row);
            goto done;
        }
        for (Py_ssize_t i = 0; i < A; i++) {
            double term = p * (double)qd[row * A + i];
            acc[i] = j == 0 ? term : acc[i] + term;
        }
    }
    result = PyList_New(A);
    for (Py_ssize_t i = 0; result != NULL && i < A; i++) {
        PyObject *v = PyFloat_FromDouble(acc[i]);
        if (v == NULL) Py_CLEAR(result);
        else PyList_SET_ITEM(result, i, v);
    }
done:
    PyMem_Free(acc);
    Py_XDECREF(probs);
    Py_XDECREF(rows);
    return result;
}

static PyMethodDef methods[] = {
    {"log_softmax_table", log_softmax_table, METH_VARARGS,
     "log_softmax_table(q_GPA, alpha) -> (G, P, A) float64 log softmax(q / alpha_g)"},
    {"mix_rows", mix_rows, METH_VARARGS,
     "mix_rows(probs, q_RA, rows) -> sum_j probs[j] q[rows[j]] as A floats"},
    {"update_rows", update_rows, METH_VARARGS,
     "update_rows(log_b, lik, pull, lam, floor_scale, floor_log) -> (E, G) array or None"},
    {"view_rows", view_rows, METH_VARARGS,
     "view_rows(log_b, k) -> per row (probs, blend_probs, top_indices, entropy) or None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_belief_row", NULL, -1, methods};

PyMODINIT_FUNC PyInit__belief_row(void) {
    import_array();
    PyObject *numpy = PyImport_ImportModule("numpy"), *math = PyImport_ImportModule("math");
    if (numpy == NULL || math == NULL) {
        Py_XDECREF(numpy);
        Py_XDECREF(math);
        return NULL;
    }
    np_exp = PyObject_GetAttrString(numpy, "exp");
    np_log = PyObject_GetAttrString(numpy, "log");
    np_logaddexp = PyObject_GetAttrString(numpy, "logaddexp");
    math_fsum = PyObject_GetAttrString(math, "fsum");
    Py_DECREF(numpy);
    Py_DECREF(math);
    if (!np_exp || !np_log || !np_logaddexp || !math_fsum) return NULL;
    return PyModule_Create(&module);
}
