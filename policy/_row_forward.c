/* policy._row_forward: many small MLPs (a stack of Q-networks), each on a few input rows, in one
 * call: the inference engine's forward at small batches (`policy.row_forward`).
 *
 * Why C: a few rows through many networks are many matrix-vector products per layer. numpy's
 * stacked matmul makes one BLAS call per network and layer and the weights stream from the
 * caches meanwhile; here the whole stack is one loop over the members, with AVX2 and FMA, that
 * takes a member's rows in blocks of 4, 2 or 1 (8 too on AVX-512) and loads each weight once
 * per block (a session's 4 partners through 35 impact networks: 4 rows a member), fetching
 * the next member's weights into the caches while it computes a member's last block (`run`).
 * Where the CPU has AVX-512F the same loops run on 16-float vectors (twice the FMAs per
 * instruction: a batch's forward is bound by them), with the same bits as on 8
 * (_row_forward_layer.h); there a layer of fewer than 8 outputs (a Q-network's actions) holds
 * two of each output's partial sums to a vector (`tail_small_avx512`).
 * The GIL is released while it runs.
 *
 * Order of operations (fixed, so the results do not depend on the batch or on the other rows):
 * - output o of a layer in a full group of 8 (or 16) outputs: acc = b[o], then for
 *   i = 0 .. I-1 acc = fma(x[i], W[i, o], acc), whatever the block of rows, the group of
 *   outputs and the vector width;
 * - the last O mod 8 outputs (the 5 actions of the final layer): four partial sums over
 *   i = 0, 4, 8 .. / 1, 5, 9 .. / 2, .. / 3, .., the first starting at b[o], the I mod 4 last
 *   inputs added to the first one in order, then (s0 + s1) + (s2 + s3);
 * - relu is max(0, v) keeping NaN (as numpy's maximum does: MAXPS returns its second operand
 *   when one is NaN), applied to a hidden layer's outputs as they are stored; tanh is libm's
 *   tanhf, over the stored outputs.
 * numpy's BLAS sums in another order, so the results differ from the numpy reference
 * (`policy.row_forward.numpy_row_forward`) by float32 rounding; tests/policy/test_row_forward.py
 * bounds the difference.
 *
 * Machines without AVX2 and FMA (or not x86-64): `AVAILABLE` is False and `forward` raises;
 * `policy.row_forward` then uses numpy. `WIDEST` is 16 where the CPU has AVX-512F, else 8 (0
 * without AVX2); `forward(..., lanes)` takes 8 or 16 (0, the default: `WIDEST`).
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

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define HAVE_X86 1

/* the last n_o mod 8 (< 8) outputs of R rows (R = 1 or 2, a constant after inlining): four
 * partial sums per row (header comment), each output a lane of a masked vector (the same
 * operations per output as a scalar loop). Each weight vector is loaded once for the R rows,
 * and two rows give 8 independent FMA chains, enough to keep both FMA pipes busy: one row
 * alone waits on the FMA latency (the 5 actions of a Q-network's last layer). */
__attribute__((target("avx2,fma"), always_inline)) static inline void
tail_rows_avx2(const float *x, int x_step, const float *W, const float *b, float *y, int y_step,
               int n_i, int n_o, int ob, const int R, int relu) {
    int lanes = n_o - ob;
    __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(lanes), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    __m256 s[2][4];
#pragma GCC unroll 2
    for (int r = 0; r < R; r++) {
        s[r][0] = _mm256_maskload_ps(b + ob, mask);
        s[r][1] = s[r][2] = s[r][3] = _mm256_setzero_ps();
    }
    const float *w = W + ob;
    int i = 0;
    for (; i + 4 <= n_i; i += 4, w += 4 * (size_t)n_o) {
        __m256 wv[4];
#pragma GCC unroll 4
        for (int k = 0; k < 4; k++) wv[k] = _mm256_maskload_ps(w + k * (size_t)n_o, mask);
#pragma GCC unroll 2
        for (int r = 0; r < R; r++)
#pragma GCC unroll 4
            for (int k = 0; k < 4; k++)
                s[r][k] = _mm256_fmadd_ps(_mm256_set1_ps(x[(size_t)r * x_step + i + k]), wv[k], s[r][k]);
    }
    for (; i < n_i; i++, w += n_o) {
        __m256 wv = _mm256_maskload_ps(w, mask);
#pragma GCC unroll 2
        for (int r = 0; r < R; r++)
            s[r][0] = _mm256_fmadd_ps(_mm256_set1_ps(x[(size_t)r * x_step + i]), wv, s[r][0]);
    }
#pragma GCC unroll 2
    for (int r = 0; r < R; r++) {
        __m256 out = _mm256_add_ps(_mm256_add_ps(s[r][0], s[r][1]), _mm256_add_ps(s[r][2], s[r][3]));
        if (relu) out = _mm256_max_ps(_mm256_setzero_ps(), out);
        _mm256_maskstore_ps(y + (size_t)r * y_step + ob, mask, out);
    }
}

/* the tail of R rows (any R), two rows at a time */
__attribute__((target("avx2,fma"), always_inline)) static inline void
tail_avx2(const float *x, int x_step, const float *W, const float *b, float *y, int y_step,
          int n_i, int n_o, int ob, int R, int relu) {
    if (ob >= n_o) return;
    int r = 0;
    for (; r + 2 <= R; r += 2)
        tail_rows_avx2(x + (size_t)r * x_step, x_step, W, b, y + (size_t)r * y_step, y_step, n_i, n_o, ob, 2, relu);
    if (r < R)
        tail_rows_avx2(x + (size_t)r * x_step, x_step, W, b, y + (size_t)r * y_step, y_step, n_i, n_o, ob, 1, relu);
}

/* a layer of fewer than 8 outputs t (the t actions of a Q-network's last layer) on R <= 8 rows,
 * AVX-512F: the same four partial sums per output as `tail_avx2`, in the same order, held two
 * to a vector. Lane k t + o of `acc[r][0]` is output o's partial sum k for k = 0, 1, of
 * `acc[r][1]` for k = 2, 3; input step j adds x[4j + k] W[4j + k, o] to it, and since W is
 * (inputs, t) row-major the 2t weights a vector needs at step j are contiguous (one load for
 * all R rows). The inputs go to their lanes by a permutation of 16 inputs loaded at once. Why:
 * `tail_avx2` loads a weight vector of t useful lanes per input and pair of rows, and
 * broadcasts every input, which gave this layer, a small share of a network's arithmetic, a
 * large share of a batch's forward (docs/performance.md, "A faster REST batch").
 * Same bits: each lane runs the partial sum's FMA chain in input order, the I mod 4 last
 * inputs go to partial sum 0 in order, then (s0 + s1) + (s2 + s3). */
__attribute__((target("avx512f,avx2,fma"), always_inline)) static inline void
tail_small_avx512(const float *x, int x_step, const float *W, const float *b, float *y,
                  int y_step, int n_i, int t, const int R, int relu) {
    const __mmask16 two = (__mmask16)((1u << (2 * t)) - 1), one = (__mmask16)((1u << t) - 1);
    __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    __m512i second = _mm512_mask_set1_epi32(_mm512_setzero_si512(),
                                            _mm512_cmpge_epi32_mask(lane, _mm512_set1_epi32(t)), 1);
    __m512i pick[4][2]; /* step jj of 4: lanes of partial sums k = 0, 1 and k = 2, 3 */
    for (int jj = 0; jj < 4; jj++) {
        pick[jj][0] = _mm512_add_epi32(_mm512_set1_epi32(4 * jj), second);
        pick[jj][1] = _mm512_add_epi32(_mm512_set1_epi32(4 * jj + 2), second);
    }
    __m512 acc[8][2];
#pragma GCC unroll 8
    for (int r = 0; r < R; r++) {
        acc[r][0] = _mm512_maskz_loadu_ps(one, b);
        acc[r][1] = _mm512_setzero_ps();
    }
    const int J = n_i / 4; /* full steps of 4 inputs */
    for (int j0 = 0; j0 < J; j0 += 4) {
        int steps = J - j0 < 4 ? J - j0 : 4;
        __mmask16 in = steps == 4 ? (__mmask16)0xFFFF : (__mmask16)((1u << (4 * steps)) - 1);
        for (int jj = 0; jj < steps; jj++) {
            const float *w = W + (size_t)(4 * (j0 + jj)) * t;
            __m512 w01 = _mm512_maskz_loadu_ps(two, w), w23 = _mm512_maskz_loadu_ps(two, w + 2 * t);
#pragma GCC unroll 8
            for (int r = 0; r < R; r++) {
                __m512 xs = _mm512_maskz_loadu_ps(in, x + (size_t)r * x_step + 4 * j0);
                acc[r][0] = _mm512_fmadd_ps(_mm512_permutexvar_ps(pick[jj][0], xs), w01, acc[r][0]);
                acc[r][1] = _mm512_fmadd_ps(_mm512_permutexvar_ps(pick[jj][1], xs), w23, acc[r][1]);
            }
        }
    }
    for (int i = 4 * J; i < n_i; i++) { /* the last I mod 4 inputs, into partial sum 0 */
        __m512 w = _mm512_maskz_loadu_ps(one, W + (size_t)i * t);
#pragma GCC unroll 8
        for (int r = 0; r < R; r++)
            acc[r][0] = _mm512_mask3_fmadd_ps(_mm512_set1_ps(x[(size_t)r * x_step + i]), w,
                                              acc[r][0], one);
    }
    __m512i down = _mm512_add_epi32(lane, _mm512_set1_epi32(t)); /* lane o + t to lane o */
#pragma GCC unroll 8
    for (int r = 0; r < R; r++) {
        __m512 s01 = _mm512_add_ps(acc[r][0], _mm512_permutexvar_ps(down, acc[r][0]));
        __m512 s23 = _mm512_add_ps(acc[r][1], _mm512_permutexvar_ps(down, acc[r][1]));
        __m512 out = _mm512_add_ps(s01, s23);
        if (relu) out = _mm512_max_ps(_mm512_setzero_ps(), out);
        _mm512_mask_storeu_ps(y + (size_t)r * y_step, one, out);
    }
}

/* the layer for 8 lanes (AVX2) and for 16 (AVX-512F): one text, _row_forward_layer.h.
 * V_OF(R): AVX2 has 16 registers (R = 4: 12 accumulators + 3 weights), AVX-512 32 */
#define SFX avx2
#define TARGET "avx2,fma"
#define VEC __m256
#define LANES 8
#define VLOAD(p) _mm256_loadu_ps(p)
#define VSTORE(p, v) _mm256_storeu_ps(p, v)
#define VFMA(a, b, c) _mm256_fmadd_ps(a, b, c)
#define VBCAST(p) _mm256_broadcast_ss(p)
#define VRELU(v) _mm256_max_ps(_mm256_setzero_ps(), v)
#define MAX_R 4
#define V_OF(R) ((R) == 4 ? 3 : (R) == 2 ? 4 : 8)
#include "_row_forward_layer.h"
#undef SFX
#undef TARGET
#undef VEC
#undef LANES
#undef VLOAD
#undef VSTORE
#undef VFMA
#undef VBCAST
#undef VRELU
#undef V_OF
#undef MAX_R

#define SFX avx512
#define TARGET "avx512f,avx2,fma"
#define VEC __m512
#define LANES 16
#define VLOAD(p) _mm512_loadu_ps(p)
#define VSTORE(p, v) _mm512_storeu_ps(p, v)
#define VFMA(a, b, c) _mm512_fmadd_ps(a, b, c)
#define VBCAST(p) _mm512_set1_ps(*(p))
#define VRELU(v) _mm512_max_ps(_mm512_setzero_ps(), v)
#define MAX_R 8
#define V_OF(R) ((R) == 8 ? 2 : (R) == 4 ? 4 : 8)
#include "_row_forward_layer.h"


/* 8 where the CPU has AVX2 and FMA, 16 where it has AVX-512F too (GCC's check includes the
 * operating system's support for the wider registers), else 0 */
static int detect_width(void) {
    __builtin_cpu_init();
    if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) return 0;
    return __builtin_cpu_supports("avx512f") ? 16 : 8;
}
#else
#define HAVE_X86 0
static int detect_width(void) { return 0; }
#endif

static int available = 0; /* AVX2 and FMA on this machine */
static int widest = 0;    /* the widest vectors this machine has: 8 or 16 floats (0: none) */

static void tanh_inplace(float *h, int n) {
    for (int i = 0; i < n; i++) h[i] = tanhf(h[i]);
}

typedef struct {
    int n_layers, n_in[MAX_LAYERS], n_out[MAX_LAYERS];
    const float *w[MAX_LAYERS], *b[MAX_LAYERS]; /* at member `start` */
} Stack;

/* every member m < M on its rows p < P: out[m, p] = mlp_m(x[m or 0, p]), in blocks of 4, 2
 * or 1 rows (`layer_avx2`), or of 8, 4, 2 or 1 when `lanes` is 16 (`layer_avx512`: 32
 * registers hold 8 rows' accumulators, and a batch loads each weight half as often). `buf`
 * holds 2 x ROW_BLOCK hidden vectors of the widest layer.
 *
 * Why fetch ahead: a session's belief passes read a stack of 35 networks' weights per call,
 * which other work evicts from the caches between requests. Without it each member's weights
 * arrive only as its own loads miss and the arithmetic waits on memory; with it the next
 * member's weights stream in while this one computes. Prefetches change no result. */
#define ROW_BLOCK 8
static void run(const Stack *s, const float *x, int x_members, int M, int P, int relu,
                float *out, float *buf, int width, int lanes) {
#if HAVE_X86
    int last = s->n_layers - 1, n_x = s->n_in[0], n_a = s->n_out[last];
    for (int m = 0; m < M; m++) {
        for (int p = 0; p < P;) {
            int R = P - p >= 8 && lanes == 16 ? 8 : P - p >= 4 ? 4 : P - p >= 2 ? 2 : 1;
            const float *h = x + ((size_t)(x_members > 1 ? m : 0) * P + p) * n_x;
            int h_step = n_x;
            for (int k = 0; k <= last; k++) {
                int n_i = s->n_in[k], n_o = s->n_out[k];
                const float *w = s->w[k] + (size_t)m * n_i * n_o, *b = s->b[k] + (size_t)m * n_o;
                float *y = k == last ? out + ((size_t)m * P + p) * n_a : buf + (size_t)(k % 2) * ROW_BLOCK * width;
                int y_step = k == last ? n_a : width;
                /* the member's last block fetches the next member's weights of this layer;
                 * not a block of one row: too little arithmetic to hide the fetch behind
                 * (measured no faster from memory, slower from the caches) */
                const float *next =
                    R > 1 && p + R == P && m + 1 < M ? w + (size_t)n_i * n_o : NULL;
                if (next != NULL) _mm_prefetch((const char *)(b + n_o), _MM_HINT_T0); /* bias */
                /* a hidden layer's relu is applied as its outputs are stored; tanh after */
                int relu_out = k < last && relu;
                if (lanes == 16)
                    layer_avx512(h, h_step, w, b, y, y_step, n_i, n_o, R, (const char *)next,
                                 relu_out);
                else
                    layer_avx2(h, h_step, w, b, y, y_step, n_i, n_o, R, (const char *)next,
                               relu_out);
                if (k < last && !relu)
                    for (int r = 0; r < R; r++) tanh_inplace(y + (size_t)r * y_step, n_o);
                h = y;
                h_step = y_step;
            }
            p += R;
        }
    }
#else
    (void)s, (void)x, (void)x_members, (void)M, (void)P, (void)relu, (void)out, (void)buf, (void)width,
        (void)lanes;
#endif
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
    int lanes = 0;
    if (!PyArg_ParseTuple(args, "OOnns|i", &x_obj, &layers, &start, &members, &activation, &lanes))
        return NULL;
    if (!available) {
        PyErr_SetString(PyExc_RuntimeError, "no compiled forward on this machine (needs AVX2 and FMA)");
        return NULL;
    }
    if (lanes == 0) lanes = widest;
    if ((lanes != 8 && lanes != 16) || lanes > widest) {
        PyErr_Format(PyExc_ValueError, "lanes: expected 0 (the widest), %s on this machine, got %d",
                     widest == 16 ? "8 or 16" : "8", lanes);
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
    float *buf = out ? malloc(2 * ROW_BLOCK * (size_t)width * sizeof(float)) : NULL;
    if (buf == NULL) {
        Py_XDECREF(out);
        if (!PyErr_Occurred()) PyErr_NoMemory();
        goto fail;
    }
    const float *x_data = (const float *)PyArray_DATA(x);
    float *out_data = (float *)PyArray_DATA((PyArrayObject *)out);
    int x_members = (int)xs[0], P = (int)xs[1];
    Py_BEGIN_ALLOW_THREADS
    run(&s, x_data, x_members, (int)members, P, relu, out_data, buf, (int)width, lanes);
    Py_END_ALLOW_THREADS
    free(buf);
    Py_DECREF(keep);
    return out;
fail:
    Py_DECREF(keep);
    return NULL;
}

/* mean_views(q_RA, views) -> (R / views, A) float64: the mean of each block of `views`
   consecutive rows, summed in float32 in order and divided in float32 (numpy's
   `np.add.reduce(q.reshape(B, views, A), axis=1) / views`, then float64): a task network's
   Q-values over the K views of each observation (`services.engine`) */
static PyObject *mean_views(PyObject *self, PyObject *args) {
    PyObject *q_obj;
    Py_ssize_t views;
    if (!PyArg_ParseTuple(args, "On", &q_obj, &views)) return NULL;
    PyArrayObject *q = (PyArrayObject *)PyArray_FROMANY(q_obj, NPY_FLOAT32, 2, 2,
                                                        NPY_ARRAY_IN_ARRAY);
    if (q == NULL) return NULL;
    npy_intp rows = PyArray_DIM(q, 0), n = PyArray_DIM(q, 1);
    if (views < 1 || rows % views != 0) {
        PyErr_Format(PyExc_ValueError, "views: expected a divisor of the %zd rows, got %zd",
                     (Py_ssize_t)rows, views);
        Py_DECREF(q);
        return NULL;
    }
    npy_intp dims[2] = {rows / views, n};
    PyObject *out = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    if (out != NULL) {
        const float *in = (const float *)PyArray_DATA(q);
        double *mean = (double *)PyArray_DATA((PyArrayObject *)out);
        for (npy_intp b = 0; b < dims[0]; b++)
            for (npy_intp a = 0; a < n; a++) {
                const float *column = in + b * views * n + a;
                float total = column[0];
                for (Py_ssize_t k = 1; k < views; k++) total += column[k * n];
                mean[b * n + a] = (double)(total / (float)views);
            }
    }
    Py_DECREF(q);
    return out;
}

static PyMethodDef methods[] = {
    {"mean_views", mean_views, METH_VARARGS, "mean_views(q_RA, views) -> (R / views, A) float64"},
    {"forward", forward, METH_VARARGS,
     "forward(x_XPF, layers, start, members, activation, lanes=0) -> (members, P, A) float32"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_row_forward", NULL, -1, methods};

PyMODINIT_FUNC PyInit__row_forward(void) {
    import_array();
    widest = detect_width();
    available = widest > 0;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (PyModule_AddObjectRef(m, "AVAILABLE", available ? Py_True : Py_False) < 0 ||
        PyModule_AddIntConstant(m, "WIDEST", widest) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
