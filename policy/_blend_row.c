/* policy._blend_row: SL / NAIL / AAIL (paper §3.3, eqs. 8-10) of B rows in one call, and AAIL's
 * policy bounded by ε (eq. R1 of `policy.regret_bound`, method aail_bounded), compiled:
 * `policy.blend.blend`'s kernel.
 *
 * Why C: the blend of one row is a few hundred double operations over vectors of a handful of
 * actions; numpy spends ~40 calls on them, and its per-call overhead, not the arithmetic, then
 * sets a single act's latency. Here every row is plain loops over doubles and libm.
 *
 * The semantics (standardisation and scale rule, the Σw = 0 fallback, rows without partners,
 * one action) are `policy.blend`'s vectorised numpy path, the reference, documented there; the
 * steps below follow it function by function. The sums run in plain order, pow is libm's and
 * exp, log and log2 libmvec's vector variants where glibc has them (`apply`; `VECTOR_MATH`: 8
 * or 4 doubles a call, 0 for libm's), so the results differ from numpy's by rounding:
 * tests/policy/test_blend_compiled.py holds them to the reference within 1e-9 on random rows
 * and rows near the corner cases (flat Q-vectors, equal policies, underflowing probabilities).
 *
 * Inputs are trusted (`policy.blend` checks them: alpha > 0, A >= 1) except for finiteness: a
 * NaN or infinite Q-value (a network's float32 output overflowed) raises FloatingPointError,
 * checked in the same pass (`policy.blend.blend_checked`). Masked partner slots are never read.
 *
 * `sample_rows` draws one action per row of a policy by inverse CDF from given uniforms, and
 * its greedy action (`policy.sampling`, whose numpy function is the reference: the same sums in
 * the same order, so the same actions).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#define FLAT_STD_RTOL 1e-12 /* policy.blend.FLAT_STD_RTOL */

static double sum(const double *x, Py_ssize_t n) {
    double total = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) total += x[i];
    return total;
}

/* ---- exp, log and log2 over a buffer: libmvec's vector variants where glibc has them ------
 * Each step gathers the values of every row into one buffer and applies one function to it
 * (`apply`). glibc's libmvec holds vector variants of exp, log and log2 (8 doubles a call with
 * AVX-512F, 4 with AVX2), several times faster a value than libm's scalar calls, which took
 * a large share of a batch's blend (docs/performance.md, "A faster REST batch"). They
 * are found at import (`dlopen`, so the module links and runs where there is no libmvec:
 * libm's then). Every value goes through the vector call, the last few padded with 1.0, so a
 * value's result depends on the value alone, never on its row or the batch (a batch's rows
 * equal the same rows blended one at a time); they may differ from libm's in the last bit
 * (glibc documents libmvec's errors within 4 ulp), far inside the module's tolerance.
 * `VECTOR_MATH` is the width found (8, 4 or 0); `vector_math(lanes)` picks another that
 * was found (or 0), so the tests hold every width to the reference on one machine. */
enum { EXP, LOG, LOG2, N_FUNCS };
static double (*const scalar_funcs[N_FUNCS])(double) = {exp, log, log2};
static const char *const vector_names[2][N_FUNCS] = {
    {"_ZGVdN4v_exp", "_ZGVdN4v_log", "_ZGVdN4v_log2"}, /* AVX2: 4 doubles */
    {"_ZGVeN8v_exp", "_ZGVeN8v_log", "_ZGVeN8v_log2"}, /* AVX-512F: 8 doubles */
};
static int vector_lanes = 0; /* doubles per vector call in use: 8, 4, or 0 (libm's scalar) */
static int lanes_found = 0;  /* the widest found at import (`VECTOR_MATH`) */

#if defined(__x86_64__) && defined(__GLIBC__)
#include <dlfcn.h>
#include <immintrin.h>
typedef __m512d (*Vec8)(__m512d);
typedef __m256d (*Vec4)(__m256d);
static void *vector_funcs[2][N_FUNCS]; /* [AVX2, AVX-512F][function], all three or none */

__attribute__((target("avx512f"))) static void apply8(Vec8 f, double *x, Py_ssize_t n) {
    Py_ssize_t i = 0;
    for (; i + 8 <= n; i += 8) _mm512_storeu_pd(x + i, f(_mm512_loadu_pd(x + i)));
    if (i == n) return;
    double pad[8] = {1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0};
    memcpy(pad, x + i, (size_t)(n - i) * sizeof(double));
    _mm512_storeu_pd(pad, f(_mm512_loadu_pd(pad)));
    memcpy(x + i, pad, (size_t)(n - i) * sizeof(double));
}

__attribute__((target("avx2"))) static void apply4(Vec4 f, double *x, Py_ssize_t n) {
    Py_ssize_t i = 0;
    for (; i + 4 <= n; i += 4) _mm256_storeu_pd(x + i, f(_mm256_loadu_pd(x + i)));
    if (i == n) return;
    double pad[4] = {1.0, 1.0, 1.0, 1.0};
    memcpy(pad, x + i, (size_t)(n - i) * sizeof(double));
    _mm256_storeu_pd(pad, f(_mm256_loadu_pd(pad)));
    memcpy(x + i, pad, (size_t)(n - i) * sizeof(double));
}

/* every width this CPU runs whose three functions libmvec holds; the widest is used */
static void find_vector_math(void) {
    __builtin_cpu_init();
    void *lib = dlopen("libmvec.so.1", RTLD_NOW | RTLD_LOCAL);
    if (lib == NULL) return;
    for (int wide = 0; wide <= 1; wide++) {
        if (!(wide ? __builtin_cpu_supports("avx512f") : __builtin_cpu_supports("avx2"))) continue;
        int found = 0;
        for (int f = 0; f < N_FUNCS; f++)
            found += (vector_funcs[wide][f] = dlsym(lib, vector_names[wide][f])) != NULL;
        if (found == N_FUNCS) lanes_found = wide ? 8 : 4;
        else memset(vector_funcs[wide], 0, sizeof vector_funcs[wide]);
    }
    vector_lanes = lanes_found;
    if (lanes_found == 0) dlclose(lib); /* else it stays open: its functions are in use */
}

static int lanes_usable(int lanes) {
    return lanes == 0 || (lanes == 8 && vector_funcs[1][0] != NULL) ||
           (lanes == 4 && vector_funcs[0][0] != NULL);
}

/* x[i] = func(x[i]) */
static void apply(int func, double *x, Py_ssize_t n) {
    if (vector_lanes == 8) apply8((Vec8)vector_funcs[1][func], x, n);
    else if (vector_lanes == 4) apply4((Vec4)vector_funcs[0][func], x, n);
    else
        for (Py_ssize_t i = 0; i < n; i++) x[i] = scalar_funcs[func](x[i]);
}
#else
static void find_vector_math(void) { (void)vector_names; }

static int lanes_usable(int lanes) { return lanes == 0; }

static void apply(int func, double *x, Py_ssize_t n) {
    for (Py_ssize_t i = 0; i < n; i++) x[i] = scalar_funcs[func](x[i]);
}
#endif

static double first_max(const double *x, Py_ssize_t n) {
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

/* ---- the steps of the blend, B rows at a time --------------------------------------------
 * Each step runs over every row; per row the operations are those of `policy.blend`'s
 * functions named below (and of `policy.maths`, which they call). */

enum { SL, NAIL, AAIL };

typedef struct {
    Py_ssize_t B, P, n;
    int method, normalise;
    const double *q_task;   /* (B, n) */
    const double *q_impact; /* (B, P, n): masked rows are never read */
    const double *alpha;    /* (B,) */
    const char *mask;       /* (B, P) */
    const double *epsilon;  /* (B,) ε of eq. R1, or NULL: no bound */
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

/* `maths.boltzmann` (eq. 2) before its exp: out = (q - max q) / alpha, `count` vectors of n */
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
        double total = sum(e, n);
        for (Py_ssize_t a = 0; a < n; a++) e[a] = e[a] / total;
    }
}

/* p divided by its sum, into `out` (as `maths` renormalises probabilities) */
static void renormalised(const double *p, Py_ssize_t n, double *out) {
    double total = sum(p, n);
    for (Py_ssize_t a = 0; a < n; a++) out[a] = total == 1.0 ? p[a] : p[a] / total;
}

/* `maths.normalized_entropy` of p, given logs[a] = log(p[a] > 0 ? p[a] : 1) */
static double entropy_finish(const double *p, const double *logs, Py_ssize_t n, double log_n) {
    double h = 0.0;
    for (Py_ssize_t a = 0; a < n; a++) h -= p[a] > 0 ? p[a] * logs[a] : 0.0;
    return py_min2(py_max2(h / log_n, 0.0), 1.0);
}

/* `blend.standardise`: z into `z`, the scale returned; z = 0 and scale 0 when flat */
static double standardise(const double *q, Py_ssize_t n, double *z, double *squares) {
    double magnitude = py_max2(first_max(q, n), -first_min(q, n));
    double divisor = magnitude > 0 ? magnitude : 1.0;
    for (Py_ssize_t a = 0; a < n; a++) z[a] = q[a] / divisor;
    double mean = sum(z, n) / n;
    for (Py_ssize_t a = 0; a < n; a++) {
        z[a] = z[a] - mean; /* the deviations */
        squares[a] = z[a] * z[a];
    }
    double std = sqrt(sum(squares, n) / n);
    if (std <= FLAT_STD_RTOL) {
        for (Py_ssize_t a = 0; a < n; a++) z[a] = 0.0;
        return 0.0;
    }
    for (Py_ssize_t a = 0; a < n; a++) z[a] = z[a] / std;
    return std * magnitude;
}

/* step 1: the Boltzmann policies of the task and (aail) of each active impact */
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
    apply(EXP, w->policies, at);
    boltzmann_finish(w->policies, at / n, n);
    return 0;
}

/* step 2: the task policy's normalised entropy, and eq. 9's (aail) on it renormalised twice */
static int entropy_step(const Batch *t, Work *w) {
    Py_ssize_t n = t->n;
    double log_n = log((double)n);
    for (Py_ssize_t b = 0; b < t->B; b++) {
        double *once = w->p_once + b * n, *twice = w->p_twice + b * n, *logs = w->logs + 2 * b * n;
        renormalised(w->policies + w->policy_at[b], n, once); /* as normalized_entropy sees it */
        renormalised(once, n, twice);                         /* as eq. 9's task_weight sees it */
        for (Py_ssize_t a = 0; a < n; a++) {
            logs[a] = once[a] > 0 ? once[a] : 1.0;
            logs[n + a] = twice[a] > 0 ? twice[a] : 1.0;
        }
    }
    apply(LOG, w->logs, 2 * t->B * n);
    for (Py_ssize_t b = 0; b < t->B; b++) {
        const double *logs = w->logs + 2 * b * n;
        t->entropy[b] = n > 1 ? entropy_finish(w->p_once + b * n, logs, n, log_n) : 0.0;
        w->h_eq9[b] = n > 1 ? entropy_finish(w->p_twice + b * n, logs + n, n, log_n) : 0.0;
    }
    return 0;
}

/* step 3 (aail): eq. 10, the JS distance of the task policy to each active impact policy
 * (`maths.js_distance`), into partner_weights' active slots; then the weights ŵ */
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
    apply(LOG2, w->ratio, at);
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
            double kl_p = sum(terms + next * n, n), kl_q = sum(terms + half + next * n, n);
            weights[s] = sqrt(py_min2(py_max2(0.5 * kl_p + 0.5 * kl_q, 0.0), 1.0));
            next++;
        }
        double total = sum(weights, P);
        for (Py_ssize_t s = 0; s < P; s++) {
            if (total > 0)
                weights[s] = weights[s] / total;
            else /* every impact policy equals the task policy: equal shares */
                weights[s] = t->mask[b * P + s] ? 1.0 / (k > 1 ? k : 1) : 0.0;
        }
    }
    return 0;
}

/* step 4: the blended Q of each row: sl the task's,  nail the raw mean, aail eq. 8
 * on standardised (`blend._aail`) or raw Q-vectors */
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
                q[0] = sum(w->scales, P);
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
                double mixed = 0.0; /* Σ_i ŵ_i Q_i */
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
        double s_blend = w_t * s_task + (1.0 - w_t) * sum(w->scales, P);
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
    apply(EXP, t->probs, t->B * n);
    boltzmann_finish(t->probs, t->B, n);
    return 0;
}

/* step 6 (aail_bounded): eq. R1 (`regret_bound.bound_rows`): the actions within ε of the
 * task's best Q share the task policy's mass on them as the blend says, every other action
 * keeps its task probability; the task policy itself where the blend puts nothing on them */
static void bound_step(const Batch *t, const Work *w) {
    Py_ssize_t n = t->n;
    for (Py_ssize_t b = 0; b < t->B; b++) {
        const double *q = t->q_task + b * n, *task = w->policies + w->policy_at[b];
        double *probs = t->probs + b * n;
        double lowest = first_max(q, n) - t->epsilon[b]; /* S_ε: q >= max q - ε */
        double task_mass = 0.0, blend_mass = 0.0;
        for (Py_ssize_t a = 0; a < n; a++)
            if (q[a] >= lowest) {
                task_mass += task[a];
                blend_mass += probs[a];
            }
        if (!(blend_mass > 0.0)) {
            memcpy(probs, task, n * sizeof(double));
            continue;
        }
        for (Py_ssize_t a = 0; a < n; a++)
            probs[a] = q[a] >= lowest ? task_mass * (probs[a] / blend_mass) : task[a];
    }
}

/* whether every Q-value the blend reads is finite (masked slots are not read) */
static int all_finite(const Batch *t) {
    Py_ssize_t n = t->n;
    for (Py_ssize_t i = 0; i < t->B * n; i++)
        if (!isfinite(t->q_task[i])) return 0;
    for (Py_ssize_t slot = 0; slot < t->B * t->P; slot++)
        if (t->mask[slot])
            for (Py_ssize_t a = 0; a < n; a++)
                if (!isfinite(t->q_impact[slot * n + a])) return 0;
    return 1;
}

/* the whole blend of a batch; 0, or -1 with a Python error set */
static int blend_batch(const Batch *t) {
    Py_ssize_t B = t->B, P = t->P, n = t->n, pairs = 0;
    if (!all_finite(t)) {
        PyErr_SetString(PyExc_FloatingPointError, "a Q-value is NaN or infinite");
        return -1;
    }
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
    if (t->method == AAIL) {
        for (Py_ssize_t b = 0; b < B; b++) power[b] = pow((double)n, w.h_eq9[b]); /* |A|^H */
        if (js_step(t, &w) < 0) goto done;
    }
    blend_step(t, &w, power);
    status = probs_step(t, &w);
    if (status == 0 && t->epsilon != NULL) bound_step(t, &w);
done:
    PyMem_Free(memory);
    PyMem_Free(counts);
    return status;
}

/* ---- Python objects in and out ------------------------------------------------------------ */

static int method_code(const char *method) {
    if (strcmp(method, "sl") == 0) return SL;
    if (strcmp(method, "nail") == 0) return NAIL;
    if (strcmp(method, "aail") == 0) return AAIL;
    PyErr_Format(PyExc_ValueError, "method: expected sl, nail or aail, got %s", method);
    return -1;
}

static PyArrayObject *float64_array(PyObject *obj, int ndim, const char *what) {
    PyArrayObject *array = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, ndim, ndim,
                                                            NPY_ARRAY_IN_ARRAY);
    if (array == NULL) PyErr_Format(PyExc_ValueError, "%s: expected a %d-d float array", what, ndim);
    return array;
}

/* blend_rows(method, q_task_BA, q_impact_BPA, alpha_B, mask_BP, normalise[, epsilon_B])
   -> (q_BA, probs_BA, task_entropy_B, task_weight_B, partner_weights_BP), float64 arrays;
   with epsilon_B (B,) (not None) the probabilities are bounded by eq. R1 (aail only) */
static PyObject *blend_rows(PyObject *self, PyObject *args) {
    const char *method_name;
    PyObject *objs[4], *epsilon_obj = Py_None;
    int normalise;
    if (!PyArg_ParseTuple(args, "sOOOOp|O", &method_name, &objs[0], &objs[1], &objs[2],
                          &objs[3], &normalise, &epsilon_obj))
        return NULL;
    int method = method_code(method_name);
    if (method < 0) return NULL;
    if (epsilon_obj != Py_None && method != AAIL) {
        PyErr_SetString(PyExc_ValueError, "epsilon_B: bounds the aail blend only");
        return NULL;
    }
    PyArrayObject *q_task = float64_array(objs[0], 2, "q_task_BA");
    PyArrayObject *q_impact = q_task ? float64_array(objs[1], 3, "q_impact_BPA") : NULL;
    PyArrayObject *alpha = q_impact ? float64_array(objs[2], 1, "alpha_B") : NULL;
    PyArrayObject *mask = alpha ? (PyArrayObject *)PyArray_FROMANY(objs[3], NPY_BOOL, 2, 2,
                                                                   NPY_ARRAY_IN_ARRAY)
                                : NULL;
    PyArrayObject *epsilon = NULL;
    PyObject *out[5] = {NULL}, *result = NULL;
    if (mask == NULL) goto done;
    if (epsilon_obj != Py_None && (epsilon = float64_array(epsilon_obj, 1, "epsilon_B")) == NULL)
        goto done;
    npy_intp B = PyArray_DIM(q_task, 0), n = PyArray_DIM(q_task, 1), P = PyArray_DIM(q_impact, 1);
    if (n < 1 || PyArray_DIM(q_impact, 0) != B || PyArray_DIM(q_impact, 2) != n ||
        PyArray_DIM(alpha, 0) != B || PyArray_DIM(mask, 0) != B || PyArray_DIM(mask, 1) != P ||
        (epsilon != NULL && PyArray_DIM(epsilon, 0) != B)) {
        PyErr_SetString(PyExc_ValueError,
                        "expected shapes (B, A), (B, P, A), (B,), (B, P)[, (B,)] with A >= 1");
        goto done;
    }
    npy_intp shapes[5][2] = {{B, n}, {B, n}, {B, 0}, {B, 0}, {B, P}};
    for (int i = 0; i < 5; i++) {
        out[i] = PyArray_SimpleNew(i == 2 || i == 3 ? 1 : 2, shapes[i], NPY_DOUBLE);
        if (out[i] == NULL) goto done;
    }
    Batch t = {B, P, n, method, normalise,
               PyArray_DATA(q_task), PyArray_DATA(q_impact), PyArray_DATA(alpha),
               PyArray_DATA(mask), epsilon == NULL ? NULL : PyArray_DATA(epsilon)};
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
    Py_XDECREF(epsilon);
    return result;
}

/* sample_rows(probs_BA, u_B) -> (actions_B, greedy_B), int64: per row the first action whose
   cumulative probability exceeds u * (the row's total), at most A - 1, and the first most
   probable action */
static PyObject *sample_rows(PyObject *self, PyObject *args) {
    PyObject *probs_obj, *u_obj, *out[2] = {NULL}, *result = NULL;
    if (!PyArg_ParseTuple(args, "OO", &probs_obj, &u_obj)) return NULL;
    PyArrayObject *probs = float64_array(probs_obj, 2, "probs_BA");
    PyArrayObject *u = probs ? float64_array(u_obj, 1, "u_B") : NULL;
    if (u == NULL) goto done;
    npy_intp B = PyArray_DIM(probs, 0), n = PyArray_DIM(probs, 1);
    if (n < 1 || PyArray_DIM(u, 0) != B) {
        PyErr_SetString(PyExc_ValueError, "expected shapes (B, A) and (B,) with A >= 1");
        goto done;
    }
    for (int i = 0; i < 2; i++)
        if ((out[i] = PyArray_SimpleNew(1, &B, NPY_INT64)) == NULL) goto done;
    const double *p = PyArray_DATA(probs), *uniform = PyArray_DATA(u);
    npy_int64 *actions = PyArray_DATA((PyArrayObject *)out[0]);
    npy_int64 *greedy = PyArray_DATA((PyArrayObject *)out[1]);
    for (npy_intp b = 0; b < B; b++, p += n) {
        /* numpy's cumsum adds in order, so the cdf here is its cdf, value for value */
        double threshold = uniform[b] * sum(p, n), cdf = 0.0;
        npy_int64 below = 0, best = 0;
        for (npy_intp a = 0; a < n; a++) {
            cdf += p[a];
            below += cdf <= threshold;
            if (p[a] > p[best]) best = a;
        }
        actions[b] = below < n - 1 ? below : n - 1;
        greedy[b] = best;
    }
    result = PyTuple_Pack(2, out[0], out[1]);
done:
    Py_XDECREF(out[0]);
    Py_XDECREF(out[1]);
    Py_XDECREF(probs);
    Py_XDECREF(u);
    return result;
}

/* vector_math([lanes]) -> the lanes in use before the call; with `lanes` (0, or 4 or 8 where
 * found) every later blend uses them: for tests and benchmarks, which compare the widths */
static PyObject *vector_math(PyObject *self, PyObject *args) {
    (void)self;
    int lanes = -1;
    if (!PyArg_ParseTuple(args, "|i", &lanes)) return NULL;
    int before = vector_lanes;
    if (lanes != -1) {
        if (!lanes_usable(lanes)) {
            PyErr_Format(PyExc_ValueError, "lanes: expected 0%s%s, got %d",
                         lanes_usable(4) ? ", 4" : "", lanes_usable(8) ? ", 8" : "", lanes);
            return NULL;
        }
        vector_lanes = lanes;
    }
    return PyLong_FromLong(before);
}

static PyMethodDef methods[] = {
    {"vector_math", vector_math, METH_VARARGS,
     "vector_math([lanes]) -> the lanes of exp/log/log2 in use before; sets them (0: libm's)"},
    {"sample_rows", sample_rows, METH_VARARGS,
     "sample_rows(probs_BA, u_B) -> (actions_B, greedy_B)"},
    {"blend_rows", blend_rows, METH_VARARGS,
     "blend_rows(method, q_task_BA, q_impact_BPA, alpha_B, mask_BP, normalise[, epsilon_B]) "
     "-> 5 arrays"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_blend_row", NULL, -1, methods};

PyMODINIT_FUNC PyInit__blend_row(void) {
    import_array();
    find_vector_math();
    PyObject *m = PyModule_Create(&module);
    if (m != NULL && PyModule_AddIntConstant(m, "VECTOR_MATH", lanes_found) < 0) Py_CLEAR(m);
    return m;
}
