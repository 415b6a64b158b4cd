/* services.rest._number_rows: a JSON batch's rows of numbers as one float64 matrix, in one pass.
 *
 * Why C: a 256-row batch body parses (orjson) into 256 lists of Python floats; pydantic's
 * `list[list[float]]` then copies every number into new lists, and `np.asarray` walks them once
 * more, discovering their type element by element: together a large share of a batch
 * request's time (docs/performance.md, "A faster REST batch").
 * This loop reads each number once and writes the array.
 *
 * `float_rows(value)` returns a C-contiguous (B, D) float64 array when `value` is a non-empty
 * list of B lists, each of the same D >= 1 entries, each entry exactly a Python float or int
 * (not a bool: a subclass of int) whose value fits a double; None for anything else, and then
 * the caller validates the value the slow way (pydantic), which accepts or refuses it exactly
 * as before and names the offending entry (`services.rest.number_rows`). It never raises for a
 * value it does not take, so it cannot change which bodies are accepted, only how fast.
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

static PyObject *float_rows(PyObject *self, PyObject *value) {
    (void)self;
    if (!PyList_CheckExact(value) || PyList_GET_SIZE(value) == 0) Py_RETURN_NONE;
    Py_ssize_t B = PyList_GET_SIZE(value);
    PyObject *first = PyList_GET_ITEM(value, 0);
    if (!PyList_CheckExact(first) || PyList_GET_SIZE(first) == 0) Py_RETURN_NONE;
    Py_ssize_t D = PyList_GET_SIZE(first);
    npy_intp dims[2] = {B, D};
    PyObject *out = PyArray_SimpleNew(2, dims, NPY_FLOAT64);
    if (out == NULL) return NULL;
    double *data = (double *)PyArray_DATA((PyArrayObject *)out);
    for (Py_ssize_t b = 0; b < B; b++) {
        PyObject *row = PyList_GET_ITEM(value, b);
        if (!PyList_CheckExact(row) || PyList_GET_SIZE(row) != D) goto other;
        for (Py_ssize_t d = 0; d < D; d++)
            if (number(PyList_GET_ITEM(row, d), data + b * D + d) < 0) goto other;
    }
    return out;
other:
    Py_DECREF(out);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"float_rows", float_rows, METH_O,
     "float_rows(value) -> a (B, D) float64 array of a list of equal lists of floats and ints, "
     "else None"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_number_rows", NULL, -1, methods};

PyMODINIT_FUNC PyInit__number_rows(void) {
    import_array();
    return PyModule_Create(&module);
}
