/* services.rest._number_rows: a JSON batch's rows of numbers as one float64 array, in one pass.
 *
 * Why C: a 256-row batch body parses (orjson) into 256 lists of Python floats; pydantic's
 * `list[list[float]]` then copies every number into new lists, and `np.asarray` walks them once
 * more, discovering their type element by element: together a large share of a batch
 * request's time (docs/performance.md, "A faster REST batch").
 * This loop reads each number once and writes the array.
 *
 * `float_array(value, ndim)` returns a C-contiguous float64 array of `ndim` dimensions when
 * `value` is `ndim` levels of non-empty lists, every list at a level as long as the first (a
 * batch's B rows of D numbers: ndim 2; B states of N agents' S numbers: 3), each entry
 * exactly a Python float or int (not a bool: a subclass of int) whose value fits a double;
 * None for anything else, and then the caller validates the value the slow way (pydantic),
 * which accepts or refuses it exactly as before and names the offending entry
 * (`services.rest.number_rows`). It never raises for a value it does not take, so it cannot
 * change which bodies are accepted, only how fast.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

/* the double of an exact float or int, or -1 (with no exception set) for anything else */
static int number(PyObject *item, double *out) {
    if (PyFloat_CheckExact(item)) {
        *out = PyFloat_AS_DOUBLE(item);
        return 0;
    }
    if (PyLong_CheckExact(item)) {
        *out = PyLong_AsDouble(item); /* beyond a double's range: OverflowError */
        if (*out == -1.0 && PyErr_Occurred()) {
            PyErr_Clear();
            return -1;
        }
        return 0;
    }
    return -1;
}

#define MAX_DIMS 4

/* the numbers of `value`, nested `ndim - depth` lists deep with the lengths of `dims[depth..]`,
 * written from `*out` on; -1 at the first thing that is not */
static int fill(PyObject *value, const npy_intp *dims, int depth, int ndim, double **out) {
    if (!PyList_CheckExact(value) || PyList_GET_SIZE(value) != dims[depth]) return -1;
    for (Py_ssize_t i = 0; i < dims[depth]; i++) {
        PyObject *item = PyList_GET_ITEM(value, i);
        if (depth + 1 < ndim) {
            if (fill(item, dims, depth + 1, ndim, out) < 0) return -1;
        } else if (number(item, (*out)++) < 0) {
            return -1;
        }
    }
    return 0;
}

static PyObject *float_array(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *value;
    int ndim;
    if (!PyArg_ParseTuple(args, "Oi", &value, &ndim)) return NULL;
    if (ndim < 1 || ndim > MAX_DIMS) {
        PyErr_Format(PyExc_ValueError, "ndim: expected 1..%d, got %d", MAX_DIMS, ndim);
        return NULL;
    }
    npy_intp dims[MAX_DIMS];
    PyObject *level = value;
    for (int d = 0; d < ndim; d++) { /* the shape, from the first entry at each depth */
        if (!PyList_CheckExact(level) || PyList_GET_SIZE(level) == 0) Py_RETURN_NONE;
        dims[d] = PyList_GET_SIZE(level);
        level = PyList_GET_ITEM(level, 0);
    }
    PyObject *out = PyArray_SimpleNew(ndim, dims, NPY_FLOAT64);
    if (out == NULL) return NULL;
    double *data = (double *)PyArray_DATA((PyArrayObject *)out);
    if (fill(value, dims, 0, ndim, &data) < 0) {
        Py_DECREF(out);
        Py_RETURN_NONE;
    }
    return out;
}

static PyMethodDef methods[] = {
    {"float_array", float_array, METH_VARARGS,
     "float_array(value, ndim) -> a float64 array of ndim nested lists of equal lengths of "
     "floats and ints, else None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_number_rows", NULL, -1, methods};

PyMODINIT_FUNC PyInit__number_rows(void) {
    import_array();
    return PyModule_Create(&module);
}
