/* One layer of the row forward for one vector width: included by _row_forward.c once for
 * AVX2 (8 lanes) and once for AVX-512 (16 lanes), with these macros defined:
 *
 *   SFX                        suffix of the functions made here (avx2, avx512)
 *   TARGET                     their target attribute ("avx2,fma", "avx512f,avx2,fma")
 *   VEC, LANES                 the vector type and its floats
 *   VLOAD(p), VSTORE(p, v)     unaligned load and store
 *   VFMA(a, b, c)              a * b + c, fused
 *   VBCAST(p)                  *p in every lane
 *   VRELU(v)                   max(0, v) lane by lane, NaN kept (MAXPS returns its second
 *                              operand, v, when either is NaN)
 *   MAX_R                      the largest block of rows (4; 8 where 32 registers hold it)
 *   V_OF(R)                    vectors per output group for a block of R rows: R * V_OF(R)
 *                              accumulators, enough independent FMAs to fill both FMA pipes,
 *                              few enough to stay in registers with the group's weights
 *
 * Why one text for both widths: the lane width decides which outputs share a register, never
 * the operations on any one output (acc = b[o], then acc = fma(x[i], W[i, o], acc) for
 * i = 0 .. I-1), so both widths give the same bits and there is one kernel to read. The
 * outputs a wide group cannot cover go on in groups of 8 (`groups_avx2`) and the tail of the
 * file's header comment (`tail_avx2`), exactly as on an AVX2-only machine.
 */
#define ROWF_CAT_(a, b) a##_##b
#define ROWF_CAT(a, b) ROWF_CAT_(a, b)

/* outputs ob.. of R rows (R = 1, 2, 4 or 8, a constant after inlining) in groups of LANES * V,
 * each weight vector loaded once for all R rows, then in groups of LANES; returns the first
 * output not done. `fetch`: the next member's weights of this layer (from `*next` to
 * `next_end`) are prefetched a few lines per input step of the wide groups. `relu`: the
 * outputs are stored as max(0, y) (a hidden layer's activation, applied while they are still
 * in registers instead of in a pass of its own over the stored rows) */
__attribute__((target(TARGET), always_inline)) static inline int
ROWF_CAT(groups, SFX)(const float *x, int x_step, const float *W, const float *b, float *y,
                      int y_step, int n_i, int n_o, int ob, const int R, const char **next,
                      const char *next_end, const int fetch, int relu) {
    const int V = V_OF(R);
    const int steps = (n_o - ob) / (LANES * V) * n_i; /* input steps of the wide groups */
    const int lines = fetch && steps ? (int)(((next_end - *next) / 64 + steps - 1) / steps) : 0;
    const char *ahead = *next;
    for (; ob + LANES * V <= n_o; ob += LANES * V) {
        VEC acc[MAX_R][8];
#pragma GCC unroll 8
        for (int r = 0; r < R; r++)
#pragma GCC unroll 8
            for (int v = 0; v < V; v++) acc[r][v] = VLOAD(b + ob + LANES * v);
        const float *w = W + ob;
        for (int i = 0; i < n_i; i++, w += n_o) {
            if (fetch)
                for (int l = 0; l < lines && ahead < next_end; l++, ahead += 64)
                    _mm_prefetch(ahead, _MM_HINT_T0);
            VEC wv[8];
#pragma GCC unroll 8
            for (int v = 0; v < V; v++) wv[v] = VLOAD(w + LANES * v);
#pragma GCC unroll 8
            for (int r = 0; r < R; r++) {
                VEC h = VBCAST(x + (size_t)r * x_step + i);
#pragma GCC unroll 8
                for (int v = 0; v < V; v++) acc[r][v] = VFMA(h, wv[v], acc[r][v]);
            }
        }
#pragma GCC unroll 8
        for (int r = 0; r < R; r++)
#pragma GCC unroll 8
            for (int v = 0; v < V; v++)
                VSTORE(y + (size_t)r * y_step + ob + LANES * v, relu ? VRELU(acc[r][v]) : acc[r][v]);
    }
    for (; ob + LANES <= n_o; ob += LANES) {
        VEC acc[MAX_R];
#pragma GCC unroll 8
        for (int r = 0; r < R; r++) acc[r] = VLOAD(b + ob);
        const float *w = W + ob;
        for (int i = 0; i < n_i; i++, w += n_o) {
            VEC wv = VLOAD(w);
#pragma GCC unroll 8
            for (int r = 0; r < R; r++)
                acc[r] = VFMA(VBCAST(x + (size_t)r * x_step + i), wv, acc[r]);
        }
#pragma GCC unroll 8
        for (int r = 0; r < R; r++) VSTORE(y + (size_t)r * y_step + ob, relu ? VRELU(acc[r]) : acc[r]);
    }
    *next = ahead;
    return ob;
}

/* one layer on R rows, y_r = W^T x_r + b (relu(...) with `relu`): the groups of this width,
 * then (wider than 8) the groups of 8, then the last n_o mod 8 outputs (`tail_avx2`); the rest
 * of the next member's weights fetched before the tail */
__attribute__((target(TARGET), always_inline)) static inline void
ROWF_CAT(layer_rows, SFX)(const float *x, int x_step, const float *W, const float *b, float *y,
                          int y_step, int n_i, int n_o, const int R, const char *next,
                          const int fetch, int relu) {
    const size_t next_lines = (size_t)n_i * n_o * sizeof(float) / 64 + 1;
    const char *next_end = fetch ? next + 64 * next_lines : next;
    int ob = ROWF_CAT(groups, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 0, R, &next, next_end,
                                   fetch, relu);
#if LANES > 8
    /* AVX2's groups hold at most 4 rows (its MAX_R) */
    int done = ob;
    for (int r = 0; r < R; r += 4)
        done = groups_avx2(x + (size_t)r * x_step, x_step, W, b, y + (size_t)r * y_step, y_step,
                           n_i, n_o, ob, R < 4 ? R : 4, &next, next_end, fetch, relu);
    ob = done;
#endif
    if (fetch)
        for (; next < next_end; next += 64) _mm_prefetch(next, _MM_HINT_T0);
#if LANES > 8
    if (n_o < 8) { /* the whole layer is its tail: two partial sums to a vector */
        tail_small_avx512(x, x_step, W, b, y, y_step, n_i, n_o, R, relu);
        return;
    }
#endif
    tail_avx2(x, x_step, W, b, y, y_step, n_i, n_o, ob, R, relu);
}

/* one layer on R = 1, 2, 4 (or 8: MAX_R) rows: `layer_rows` made for each R, with and without
 * fetching `next` (the same weights of the next member, or NULL; why: `run`) */
__attribute__((target(TARGET))) static void
ROWF_CAT(layer, SFX)(const float *x, int x_step, const float *W, const float *b, float *y,
                     int y_step, int n_i, int n_o, int R, const char *next, int relu) {
#if MAX_R == 8
    if (R == 8) {
        if (next == NULL) ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 8, NULL, 0, relu);
        else ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 8, next, 1, relu);
        return;
    }
#endif
    if (next == NULL) {
        if (R == 4) ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 4, NULL, 0, relu);
        else if (R == 2) ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 2, NULL, 0, relu);
        else ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 1, NULL, 0, relu);
    } else {
        if (R == 4) ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 4, next, 1, relu);
        else if (R == 2) ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 2, next, 1, relu);
        else ROWF_CAT(layer_rows, SFX)(x, x_step, W, b, y, y_step, n_i, n_o, 1, next, 1, relu);
    }
}
