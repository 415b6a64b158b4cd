/* policy._row_forward: many small MLPs (a stack of Q-networks), each on a few input rows, in one
 * call: the single-observation forward of the inference engine (`policy.row_forward`).
 *
 * Why C: one observation through 35 networks of 8-128-128-5 is 35 matrix-vector products per
 * layer. numpy's stacked matmul makes one BLAS call per network and layer (~0.5 µs each) and
 * the weights (2.5 MB) stream from L3 meanwhile; here the whole stack is one loop that reads
 * each weight once, at close to the cache's bandwidth (~45 against ~90 µs on the dev machine,
 * weights not in L2). The GIL is released while it runs.
 *
 * The order of operations is fixed, so the AVX-512 and the AVX2 builds give the same bits:
 * - output o of a layer in a full group of 8 outputs: acc = b[o], then for i = 0 .. I-1
 *   acc = fma(x[i], W[i, o], acc) (one rounding per step);
 * - the last O mod 8 outputs (the 5 actions of the final layer): four partial sums over
 *   i = 0, 4, 8 .. / 1, 5, 9 .. / 2, .. / 3, .., the first starting at b[o], the I mod 4 last
 *   inputs added to the first one in order, then (s0 + s1) + (s2 + s3) (a single chain would
 *   wait on the FMA latency at every step);
 * - relu is max(0, v) keeping NaN (as numpy's maximum does); tanh is libm's tanhf.
 * With AVX-512, two rows of a member (two partners' views) go through its weights together,
 * each weight loaded once for both; every output's operations stay the ones above.
 * numpy's BLAS sums in another order, so the results differ from `policy.qnet`'s numpy forward
 * in the last bits (tests/policy/test_row_forward.py bounds it).
 *
 * Machines without AVX2 and FMA (or not x86-64): `VARIANT` is "none" and `forward` raises;
 * `policy.row_forward` then uses numpy.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#define MAX_LAYERS 16

typedef void (*matvec_fn)(const float *x, const float *W, const float *b, float *y, int n_i, int n_o);

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define HAVE_X86 1

/* the last n_o mod 8 (< 8) outputs: four partial sums (header comment), each output a lane
 * of a masked vector (the same operations per output as a scalar loop, one FMA latency per
 * 4 inputs for all of them) */
__attribute__((target("avx2,fma"))) static void tail_avx2(const float *x, const float *W,
                                                         const float *b, float *y, int n_i,
                                                         int n_o, int ob) {
    if (ob >= n_o) return;
    int lanes = n_o - ob;
    __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(lanes), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    __m256 s0 = _mm256_maskload_ps(b + ob, mask), s1 = _mm256_setzero_ps(), s2 = s1, s3 = s1;
    const float *r = W + ob;
    int i = 0;
    for (; i + 4 <= n_i; i += 4, r += 4 * (size_t)n_o) {
        s0 = _mm256_fmadd_ps(_mm256_set1_ps(x[i]), _mm256_maskload_ps(r, mask), s0);
        s1 = _mm256_fmadd_ps(_mm256_set1_ps(x[i + 1]), _mm256_maskload_ps(r + n_o, mask), s1);
        s2 = _mm256_fmadd_ps(_mm256_set1_ps(x[i + 2]), _mm256_maskload_ps(r + 2 * (size_t)n_o, mask), s2);
        s3 = _mm256_fmadd_ps(_mm256_set1_ps(x[i + 3]), _mm256_maskload_ps(r + 3 * (size_t)n_o, mask), s3);
    }
    for (; i < n_i; i++, r += n_o)
        s0 = _mm256_fmadd_ps(_mm256_set1_ps(x[i]), _mm256_maskload_ps(r, mask), s0);
    _mm256_maskstore_ps(y + ob, mask, _mm256_add_ps(_mm256_add_ps(s0, s1), _mm256_add_ps(s2, s3)));
}

__attribute__((target("avx512f,fma"))) static void tail_avx512(const float *x, const float *W,
                                                              const float *b, float *y, int n_i,
                                                              int n_o, int ob) {
    if (ob >= n_o) return;
    __mmask16 mask = (__mmask16)((1u << (n_o - ob)) - 1);
    __m512 s0 = _mm512_maskz_loadu_ps(mask, b + ob), s1 = _mm512_setzero_ps(), s2 = s1, s3 = s1;
    const float *r = W + ob;
    int i = 0;
    for (; i + 4 <= n_i; i += 4, r += 4 * (size_t)n_o) {
        s0 = _mm512_fmadd_ps(_mm512_set1_ps(x[i]), _mm512_maskz_loadu_ps(mask, r), s0);
        s1 = _mm512_fmadd_ps(_mm512_set1_ps(x[i + 1]), _mm512_maskz_loadu_ps(mask, r + n_o), s1);
        s2 = _mm512_fmadd_ps(_mm512_set1_ps(x[i + 2]), _mm512_maskz_loadu_ps(mask, r + 2 * (size_t)n_o), s2);
        s3 = _mm512_fmadd_ps(_mm512_set1_ps(x[i + 3]), _mm512_maskz_loadu_ps(mask, r + 3 * (size_t)n_o), s3);
    }
    for (; i < n_i; i++, r += n_o)
        s0 = _mm512_fmadd_ps(_mm512_set1_ps(x[i]), _mm512_maskz_loadu_ps(mask, r), s0);
    _mm512_mask_storeu_ps(y + ob, mask, _mm512_add_ps(_mm512_add_ps(s0, s1), _mm512_add_ps(s2, s3)));
}

/* y (n_o) = b + x (n_i) @ W (n_i, n_o), W row-major: AVX-512, 128 outputs per pass in 8 registers */
__attribute__((target("avx512f,fma"))) static void matvec_avx512_from(const float *x,
                                                                     const float *W,
                                                                     const float *b, float *y,
                                                                     int n_i, int n_o, int ob) {
    for (; ob + 128 <= n_o; ob += 128) {
        __m512 a0 = _mm512_loadu_ps(b + ob), a1 = _mm512_loadu_ps(b + ob + 16);
        __m512 a2 = _mm512_loadu_ps(b + ob + 32), a3 = _mm512_loadu_ps(b + ob + 48);
        __m512 a4 = _mm512_loadu_ps(b + ob + 64), a5 = _mm512_loadu_ps(b + ob + 80);
        __m512 a6 = _mm512_loadu_ps(b + ob + 96), a7 = _mm512_loadu_ps(b + ob + 112);
        const float *r = W + ob;
        for (int i = 0; i < n_i; i++, r += n_o) {
            __m512 h = _mm512_set1_ps(x[i]);
            a0 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r), a0);
            a1 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 16), a1);
            a2 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 32), a2);
            a3 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 48), a3);
            a4 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 64), a4);
            a5 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 80), a5);
            a6 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 96), a6);
            a7 = _mm512_fmadd_ps(h, _mm512_loadu_ps(r + 112), a7);
        }
        _mm512_storeu_ps(y + ob, a0), _mm512_storeu_ps(y + ob + 16, a1);
        _mm512_storeu_ps(y + ob + 32, a2), _mm512_storeu_ps(y + ob + 48, a3);
        _mm512_storeu_ps(y + ob + 64, a4), _mm512_storeu_ps(y + ob + 80, a5);
        _mm512_storeu_ps(y + ob + 96, a6), _mm512_storeu_ps(y + ob + 112, a7);
    }
    for (; ob + 16 <= n_o; ob += 16) {
        __m512 a = _mm512_loadu_ps(b + ob);
        const float *r = W + ob;
        for (int i = 0; i < n_i; i++, r += n_o) a = _mm512_fmadd_ps(_mm512_set1_ps(x[i]), _mm512_loadu_ps(r), a);
        _mm512_storeu_ps(y + ob, a);
    }
    if (ob + 8 <= n_o) {
        __m256 a = _mm256_loadu_ps(b + ob);
        const float *r = W + ob;
        for (int i = 0; i < n_i; i++, r += n_o) a = _mm256_fmadd_ps(_mm256_set1_ps(x[i]), _mm256_loadu_ps(r), a);
        _mm256_storeu_ps(y + ob, a);
        ob += 8;
    }
    tail_avx512(x, W, b, y, n_i, n_o, ob);
}

__attribute__((target("avx512f,fma"))) static void matvec_avx512(const float *x, const float *W,
                                                                const float *b, float *y, int n_i,
                                                                int n_o) {
    matvec_avx512_from(x, W, b, y, n_i, n_o, 0);
}

/* two rows through the same weights in one pass (each weight loaded once for both): the
 * 128-output blocks with 8 accumulators per row, the rest row by row; every output's
 * operations are those of matvec_avx512, so the bits are too */
__attribute__((target("avx512f,fma"))) static void matvec2_avx512(const float *xa,
                                                                 const float *xb,
                                                                 const float *W, const float *b,
                                                                 float *ya, float *yb, int n_i,
                                                                 int n_o) {
    int ob = 0;
    for (; ob + 128 <= n_o; ob += 128) {
        __m512 a0 = _mm512_loadu_ps(b + ob), a1 = _mm512_loadu_ps(b + ob + 16);
        __m512 a2 = _mm512_loadu_ps(b + ob + 32), a3 = _mm512_loadu_ps(b + ob + 48);
        __m512 a4 = _mm512_loadu_ps(b + ob + 64), a5 = _mm512_loadu_ps(b + ob + 80);
        __m512 a6 = _mm512_loadu_ps(b + ob + 96), a7 = _mm512_loadu_ps(b + ob + 112);
        __m512 c0 = a0, c1 = a1, c2 = a2, c3 = a3, c4 = a4, c5 = a5, c6 = a6, c7 = a7;
        const float *r = W + ob;
        for (int i = 0; i < n_i; i++, r += n_o) {
            __m512 ha = _mm512_set1_ps(xa[i]), hb = _mm512_set1_ps(xb[i]), w;
            w = _mm512_loadu_ps(r), a0 = _mm512_fmadd_ps(ha, w, a0), c0 = _mm512_fmadd_ps(hb, w, c0);
            w = _mm512_loadu_ps(r + 16), a1 = _mm512_fmadd_ps(ha, w, a1), c1 = _mm512_fmadd_ps(hb, w, c1);
            w = _mm512_loadu_ps(r + 32), a2 = _mm512_fmadd_ps(ha, w, a2), c2 = _mm512_fmadd_ps(hb, w, c2);
            w = _mm512_loadu_ps(r + 48), a3 = _mm512_fmadd_ps(ha, w, a3), c3 = _mm512_fmadd_ps(hb, w, c3);
            w = _mm512_loadu_ps(r + 64), a4 = _mm512_fmadd_ps(ha, w, a4), c4 = _mm512_fmadd_ps(hb, w, c4);
            w = _mm512_loadu_ps(r + 80), a5 = _mm512_fmadd_ps(ha, w, a5), c5 = _mm512_fmadd_ps(hb, w, c5);
            w = _mm512_loadu_ps(r + 96), a6 = _mm512_fmadd_ps(ha, w, a6), c6 = _mm512_fmadd_ps(hb, w, c6);
            w = _mm512_loadu_ps(r + 112), a7 = _mm512_fmadd_ps(ha, w, a7), c7 = _mm512_fmadd_ps(hb, w, c7);
        }
        _mm512_storeu_ps(ya + ob, a0), _mm512_storeu_ps(ya + ob + 16, a1);
        _mm512_storeu_ps(ya + ob + 32, a2), _mm512_storeu_ps(ya + ob + 48, a3);
        _mm512_storeu_ps(ya + ob + 64, a4), _mm512_storeu_ps(ya + ob + 80, a5);
        _mm512_storeu_ps(ya + ob + 96, a6), _mm512_storeu_ps(ya + ob + 112, a7);
        _mm512_storeu_ps(yb + ob, c0), _mm512_storeu_ps(yb + ob + 16, c1);
        _mm512_storeu_ps(yb + ob + 32, c2), _mm512_storeu_ps(yb + ob + 48, c3);
        _mm512_storeu_ps(yb + ob + 64, c4), _mm512_storeu_ps(yb + ob + 80, c5);
        _mm512_storeu_ps(yb + ob + 96, c6), _mm512_storeu_ps(yb + ob + 112, c7);
    }
    if (ob < n_o) {
        matvec_avx512_from(xa, W, b, ya, n_i, n_o, ob);
        matvec_avx512_from(xb, W, b, yb, n_i, n_o, ob);
    }
}

/* the same with AVX2: 64 outputs per pass in 8 registers */
__attribute__((target("avx2,fma"))) static void matvec_avx2(const float *x, const float *W,
                                                           const float *b, float *y, int n_i,
                                                           int n_o) {
    int ob = 0;
    for (; ob + 64 <= n_o; ob += 64) {
        __m256 a0 = _mm256_loadu_ps(b + ob), a1 = _mm256_loadu_ps(b + ob + 8);
        __m256 a2 = _mm256_loadu_ps(b + ob + 16), a3 = _mm256_loadu_ps(b + ob + 24);
        __m256 a4 = _mm256_loadu_ps(b + ob + 32), a5 = _mm256_loadu_ps(b + ob + 40);
        __m256 a6 = _mm256_loadu_ps(b + ob + 48), a7 = _mm256_loadu_ps(b + ob + 56);
        const float *r = W + ob;
        for (int i = 0; i < n_i; i++, r += n_o) {
            __m256 h = _mm256_broadcast_ss(x + i);
            a0 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r), a0);
            a1 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 8), a1);
            a2 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 16), a2);
            a3 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 24), a3);
            a4 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 32), a4);
            a5 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 40), a5);
            a6 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 48), a6);
            a7 = _mm256_fmadd_ps(h, _mm256_loadu_ps(r + 56), a7);
        }
        _mm256_storeu_ps(y + ob, a0), _mm256_storeu_ps(y + ob + 8, a1);
        _mm256_storeu_ps(y + ob + 16, a2), _mm256_storeu_ps(y + ob + 24, a3);
        _mm256_storeu_ps(y + ob + 32, a4), _mm256_storeu_ps(y + ob + 40, a5);
        _mm256_storeu_ps(y + ob + 48, a6), _mm256_storeu_ps(y + ob + 56, a7);
    }
    for (; ob + 8 <= n_o; ob += 8) {
        __m256 a = _mm256_loadu_ps(b + ob);
        const float *r = W + ob;
        for (int i = 0; i < n_i; i++, r += n_o) a = _mm256_fmadd_ps(_mm256_broadcast_ss(x + i), _mm256_loadu_ps(r), a);
        _mm256_storeu_ps(y + ob, a);
    }
    tail_avx2(x, W, b, y, n_i, n_o, ob);
}

/* max(0, v), NaN kept (MAXPS returns its second operand when one is NaN) */
__attribute__((target("avx2"))) static void relu_avx2(float *h, int n) {
    int i = 0;
    __m256 zero = _mm256_setzero_ps();
    for (; i + 8 <= n; i += 8) _mm256_storeu_ps(h + i, _mm256_max_ps(zero, _mm256_loadu_ps(h + i)));
    for (; i < n; i++) h[i] = 0.0f > h[i] ? 0.0f : h[i];
}

static int detect_variant(void) {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("fma")) return 512;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return 256;
    return 0;
}
#else
#define HAVE_X86 0
static int detect_variant(void) { return 0; }
#endif

static int variant = 0; /* 512, 256 or 0 (no compiled forward on this machine) */

static void tanh_inplace(float *h, int n) {
    for (int i = 0; i < n; i++) h[i] = tanhf(h[i]);
}

typedef struct {
    int n_layers, n_in[MAX_LAYERS], n_out[MAX_LAYERS];
    const float *w[MAX_LAYERS], *b[MAX_LAYERS]; /* at member `start` */
} Stack;

static void activate(float *y, int n, int relu) {
#if HAVE_X86
    if (relu) relu_avx2(y, n);
    else tanh_inplace(y, n);
#else
    (void)y, (void)n, (void)relu;
#endif
}

/* every member m < M on its rows p < P: out[m, p] = mlp_m(x[m or 0, p]); with AVX-512 two rows
 * at a time share each weight load (matvec2_avx512: the same bits). `buf` holds 4 hidden
 * vectors of the widest layer. */
static void run(const Stack *s, const float *x, int x_members, int M, int P, int relu,
                float *out, float *buf, int width) {
#if HAVE_X86
    matvec_fn matvec = variant == 512 ? matvec_avx512 : matvec_avx2;
    int pairs = variant == 512;
#else
    matvec_fn matvec = NULL;
    int pairs = 0;
#endif
    int last = s->n_layers - 1, n_x = s->n_in[0], n_a = s->n_out[last];
    for (int m = 0; m < M; m++) {
        int p = 0;
#if HAVE_X86
        for (; pairs && p + 2 <= P; p += 2) {
            const float *ha = x + ((size_t)(x_members > 1 ? m : 0) * P + p) * n_x, *hb = ha + n_x;
            for (int k = 0; k <= last; k++) {
                int n_i = s->n_in[k], n_o = s->n_out[k];
                const float *w = s->w[k] + (size_t)m * n_i * n_o, *b = s->b[k] + (size_t)m * n_o;
                float *ya = k == last ? out + ((size_t)m * P + p) * n_a : buf + (k % 2) * width;
                float *yb = k == last ? ya + n_a : buf + (2 + k % 2) * width;
                matvec2_avx512(ha, hb, w, b, ya, yb, n_i, n_o);
                if (k < last) activate(ya, n_o, relu), activate(yb, n_o, relu);
                ha = ya, hb = yb;
            }
        }
#endif
        for (; p < P; p++) {
            const float *h = x + ((size_t)(x_members > 1 ? m : 0) * P + p) * n_x;
            for (int k = 0; k <= last; k++) {
                int n_i = s->n_in[k], n_o = s->n_out[k];
                const float *w = s->w[k] + (size_t)m * n_i * n_o, *b = s->b[k] + (size_t)m * n_o;
                float *y = k == last ? out + ((size_t)m * P + p) * n_a : buf + (k % 2) * width;
                matvec(h, w, b, y, n_i, n_o);
                if (k < last) activate(y, n_o, relu);
                h = y;
            }
        }
    }
}

/* a float32 C-contiguous array of `ndim` dimensions, or NULL with an exception naming `what` */
static PyArrayObject *float32_array(PyObject *obj, int ndim, const char *what) {
    if (!PyArray_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "%s: expected a numpy array", what);
        return NULL;
    }
    PyArrayObject *arr = (PyArrayObject *)obj;
    if (PyArray_TYPE(arr) != NPY_FLOAT32 || !PyArray_IS_C_CONTIGUOUS(arr) ||
        PyArray_NDIM(arr) != ndim) {
        PyErr_Format(PyExc_ValueError, "%s: expected a C-contiguous float32 array of %d dimensions",
                     what, ndim);
        return NULL;
    }
    return arr;
}

static PyObject *forward(PyObject *self, PyObject *args) {
    PyObject *x_obj, *layers;
    Py_ssize_t start, members;
    const char *activation;
    if (!PyArg_ParseTuple(args, "OOnns", &x_obj, &layers, &start, &members, &activation))
        return NULL;
    if (variant == 0) {
        PyErr_SetString(PyExc_RuntimeError, "no compiled forward on this machine (needs AVX2 and FMA)");
        return NULL;
    }
    int relu = strcmp(activation, "relu") == 0;
    if (!relu && strcmp(activation, "tanh") != 0) {
        PyErr_Format(PyExc_ValueError, "activation: expected 'relu' or 'tanh', got '%s'", activation);
        return NULL;
    }
    PyArrayObject *x = float32_array(x_obj, 3, "x");
    if (x == NULL) return NULL;
    npy_intp *xs = PyArray_DIMS(x);
    if (!PySequence_Check(layers)) {
        PyErr_SetString(PyExc_TypeError, "layers: expected a sequence of (weight, bias) pairs");
        return NULL;
    }
    Py_ssize_t n_layers = PySequence_Size(layers);
    if (n_layers < 1 || n_layers > MAX_LAYERS) {
        PyErr_Format(PyExc_ValueError, "layers: expected 1..%d layers, got %zd", MAX_LAYERS, n_layers);
        return NULL;
    }
    if (members < 1 || members > INT_MAX || start < 0 || xs[1] > INT_MAX ||
        (xs[0] != 1 && xs[0] != members)) {
        PyErr_Format(PyExc_ValueError, "x: expected (1 or %zd, P, F) rows with start >= 0, got %zd rows",
                     members, (Py_ssize_t)xs[0]);
        return NULL;
    }
    Stack s;
    s.n_layers = (int)n_layers;
    Py_ssize_t width = 1, n_in = xs[2];
    PyObject *keep = PyTuple_New(2 * n_layers); /* holds the arrays while the GIL is released */
    if (keep == NULL) return NULL;
    for (Py_ssize_t k = 0; k < n_layers; k++) {
        PyObject *pair = PySequence_GetItem(layers, k), *w_obj = NULL, *b_obj = NULL;
        if (pair == NULL) goto fail;
        if (PySequence_Check(pair) && PySequence_Size(pair) == 2) {
            w_obj = PySequence_GetItem(pair, 0);
            b_obj = PySequence_GetItem(pair, 1);
        }
        Py_DECREF(pair);
        PyTuple_SET_ITEM(keep, 2 * k, w_obj ? w_obj : Py_NewRef(Py_None));
        PyTuple_SET_ITEM(keep, 2 * k + 1, b_obj ? b_obj : Py_NewRef(Py_None));
        if (w_obj == NULL || b_obj == NULL) {
            PyErr_Format(PyExc_TypeError, "layers[%zd]: expected a (weight, bias) pair", k);
            goto fail;
        }
        char w_name[32], b_name[32];
        snprintf(w_name, sizeof w_name, "layers[%d][0]", (int)k);
        snprintf(b_name, sizeof b_name, "layers[%d][1]", (int)k);
        PyArrayObject *w = float32_array(w_obj, 3, w_name);
        PyArrayObject *b = w ? float32_array(b_obj, 3, b_name) : NULL;
        if (b == NULL) goto fail;
        npy_intp *ws = PyArray_DIMS(w), *bs = PyArray_DIMS(b);
        if (ws[1] != n_in || bs[0] != ws[0] || bs[1] != 1 || bs[2] != ws[2] ||
            start + members > ws[0] || ws[2] < 1 || ws[1] > INT_MAX || ws[2] > INT_MAX) {
            PyErr_Format(PyExc_ValueError,
                         "layers[%zd]: expected weights (R >= %zd, %zd, out) and bias (R, 1, out)",
                         k, start + members, n_in);
            goto fail;
        }
        s.n_in[k] = (int)n_in;
        s.n_out[k] = (int)ws[2];
        s.w[k] = (const float *)PyArray_DATA(w) + (size_t)start * ws[1] * ws[2];
        s.b[k] = (const float *)PyArray_DATA(b) + (size_t)start * ws[2];
        n_in = ws[2];
        if (n_in > width) width = n_in;
    }
    npy_intp dims[3] = {members, xs[1], n_in};
    PyObject *out = PyArray_SimpleNew(3, dims, NPY_FLOAT32);
    float *buf = out ? malloc(4 * (size_t)width * sizeof(float)) : NULL;
    if (buf == NULL) {
        Py_XDECREF(out);
        if (!PyErr_Occurred()) PyErr_NoMemory();
        goto fail;
    }
    const float *x_data = (const float *)PyArray_DATA(x);
    float *out_data = (float *)PyArray_DATA((PyArrayObject *)out);
    int x_members = (int)xs[0], P = (int)xs[1];
    Py_BEGIN_ALLOW_THREADS
    run(&s, x_data, x_members, (int)members, P, relu, out_data, buf, (int)width);
    Py_END_ALLOW_THREADS
    free(buf);
    Py_DECREF(keep);
    return out;
fail:
    Py_DECREF(keep);
    return NULL;
}

/* all_finite(a) -> bool: every entry of a C-contiguous float32 array is finite */
static PyObject *all_finite(PyObject *self, PyObject *obj) {
    if (!PyArray_Check(obj) || PyArray_TYPE((PyArrayObject *)obj) != NPY_FLOAT32 ||
        !PyArray_IS_C_CONTIGUOUS((PyArrayObject *)obj)) {
        PyErr_SetString(PyExc_ValueError, "a: expected a C-contiguous float32 array");
        return NULL;
    }
    const float *data = PyArray_DATA((PyArrayObject *)obj);
    npy_intp n = PyArray_SIZE((PyArrayObject *)obj);
    for (npy_intp i = 0; i < n; i++)
        if (!isfinite(data[i])) Py_RETURN_FALSE;
    Py_RETURN_TRUE;
}

static const char *variant_name(int v) { return v == 512 ? "avx512" : v == 256 ? "avx2" : "none"; }

/* tests: run a narrower variant than the machine's (the bits must not change) */
static PyObject *set_variant(PyObject *self, PyObject *arg) {
    const char *name = PyUnicode_AsUTF8(arg);
    if (name == NULL) return NULL;
    int wanted = strcmp(name, "avx512") == 0 ? 512 : strcmp(name, "avx2") == 0 ? 256 : -1;
    if (wanted < 0 || wanted > detect_variant()) {
        PyErr_Format(PyExc_ValueError, "variant: '%s' is not available on this machine", name);
        return NULL;
    }
    const char *previous = variant_name(variant);
    variant = wanted;
    return PyUnicode_FromString(previous);
}

static PyMethodDef methods[] = {
    {"forward", forward, METH_VARARGS,
     "forward(x_XPF, layers, start, members, activation) -> (members, P, A) float32"},
    {"all_finite", all_finite, METH_O, "all_finite(a) -> whether every float32 entry is finite"},
    {"set_variant", set_variant, METH_O, "set_variant('avx2' | 'avx512') -> the previous one"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_row_forward", NULL, -1, methods};

PyMODINIT_FUNC PyInit__row_forward(void) {
    import_array();
    variant = detect_variant();
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (PyModule_AddStringConstant(m, "VARIANT", variant_name(variant)) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
