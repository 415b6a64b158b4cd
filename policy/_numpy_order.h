/* Arithmetic in numpy's own order, for C code that must give numpy's bits (policy/_blend_row.c,
 * policy/_belief_row.c): numpy's pairwise sum of a contiguous float64 run, and a numpy ufunc
 * applied in place to a C buffer (numpy's SIMD exp and log can differ from libm's in the last
 * bit, so the C code calls numpy's). Include after numpy/arrayobject.h. */
#ifndef COEXIST_NUMPY_ORDER_H
#define COEXIST_NUMPY_ORDER_H

#include <string.h>

#define PAIRWISE_BLOCK 128 /* numpy's PW_BLOCKSIZE */

/* ---- sums in numpy's order ---------------------------------------------------------------- */

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

#endif
