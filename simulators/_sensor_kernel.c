/* The simulated camera's sensor read-out (rig.simulators.sensor.SensorModel.read) on a band of rows, compiled.
 *
 * Per pixel, as the numpy path does (float32 arithmetic except inside the samplers, which work in double):
 * mean = dark·t + (L·s)·response, capped at guard·full well; the charge is N(mean, mean + σd²) where the
 * skewness criterion of sensor.electrons lets the normal stand for Poisson(mean) + N(0, σd²), else an exact
 * Poisson(mean) plus the read noise; then the full-well clip, the optional nonlinearity, the gain, the black
 * level, rounding and the ADC clip to uint16. No -ffast-math: IEEE arithmetic throughout.
 *
 * Random numbers: xoshiro256** (Blackman & Vigna 2018, "Scrambled linear pseudorandom number generators"),
 * seeded per row of the window from (frame seed, row) through SplitMix64, so a frame depends neither on how
 * its rows are split into bands nor on the number of CPUs.
 * Normal deviates: the ziggurat of Marsaglia & Tsang (2000, "The ziggurat method for generating random
 * variables", J. Stat. Softw. 5(8)) with 256 layers, tables built at import, 52-bit uniforms as numpy's;
 * exact tail beyond r (Marsaglia 1964) and the wedge test under exp(−x²/2).
 * Poisson deviates, exact: inversion by sequential search for mean < 10; for mean ≥ 10 Ahrens & Dieter's
 * algorithm PD (1982, "Computer generation of Poisson deviates from modified normal distributions", ACM
 * TOMS 8(2) 163–179): a normal proposal ⌊mean + √mean·T⌋ accepted at once where the Poisson pmf exceeds the
 * normal cell probability (most draws: one normal, no logarithm), else a squeeze, a quotient test and a
 * Laplace hat for the difference. Chosen over Hörmann's PTRS (numpy's), whose quick acceptance needs two
 * uniforms, a square root and two divisions per draw and which takes its logarithms ~40% of the time at mean
 * 50: PD is about 3× faster per draw (19 against 56 ns at mean 50 on a 2 GHz Zen 1, its normal included).
 * Its premises (pmf ≥ normal cell from ⌊mean − 1.1484⌋ up, the squeeze inside the quotient test, the hat
 * majorising the difference with 0.1069/mean, pmf < normal cell below mean − 0.6744·√mean) were checked
 * numerically for mean 10 … 5000, and its series for the normal cell is exact to 1e-10 in total variation.
 *
 * Inputs are read through the buffer protocol (no numpy headers): response and dark current float32 (H, W)
 * with any strides (windows of the full-sensor arrays), the luminance a float or a float64/float32 (H, W)
 * array; the output a writable C-contiguous uint16 (H, W). The GIL is released over the rows.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#elif defined(__ARM_NEON) && defined(__aarch64__)
#include <arm_neon.h>
#endif

#if defined(__GNUC__)
#define INLINE static inline __attribute__((always_inline))
#else
#define INLINE static inline
#endif

/* ---- generator ------------------------------------------------------------------------------------------ */

typedef struct { uint64_t s[4]; } Rng;

static uint64_t splitmix64(uint64_t *z) {
    uint64_t r = (*z += 0x9E3779B97F4A7C15ULL);
    r = (r ^ (r >> 30)) * 0xBF58476D1CE4E5B9ULL;
    r = (r ^ (r >> 27)) * 0x94D049BB133111EBULL;
    return r ^ (r >> 31);
}

/* The stream of row `row` of a frame of seed `seed`: a SplitMix64 hash of (seed, row) seeds a second SplitMix64
 * that fills the state (never all zero: SplitMix64's output is a bijection of its distinct states). */
static void rng_seed(Rng *g, uint64_t seed, uint64_t row) {
    uint64_t z = seed + row * 0x9E3779B97F4A7C15ULL;
    uint64_t key = splitmix64(&z);
    for (int i = 0; i < 4; i++) g->s[i] = splitmix64(&key);
}

INLINE uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

INLINE uint64_t next64(Rng *g) {
    uint64_t *s = g->s;
    const uint64_t out = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0]; s[3] ^= s[1]; s[1] ^= s[2]; s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return out;
}

/* Uniform on [0, 1) in steps of 2⁻⁵³. */
INLINE double uniform(Rng *g) { return (double)(next64(g) >> 11) * 0x1.0p-53; }

/* ---- normal: ziggurat ----------------------------------------------------------------------------------- */

#define ZIG_LAYERS 256
/* x of the lowest layer's top for 256 layers (the root that closes the ziggurat, as numpy's constant) */
static const double ZIG_R = 3.6541528853610088;
static uint64_t zig_k[ZIG_LAYERS];   /* accept j < k[i] without evaluating exp: x_{i-1}/x_i · 2⁵² */
static double zig_w[ZIG_LAYERS];     /* x_i / 2⁵²: j·w[i] is uniform on [0, x_i) */
static double zig_f[ZIG_LAYERS];     /* exp(−x_i²/2); f[0] = 1, the top of layer 1 */

/* Layer i ≥ 1 is the rectangle [0, x_i) × [f(x_i), f(x_{i−1})] with x_255 = r > … > x_1 > x_0 = 0, each of area
 * v; layer 0 is the base [0, v/f(r)) × [0, f(r)] merged with the tail beyond r (also of area v).
 * Returns 0 when the recursion does not close (x_1 (1 − f(x_1)) = v), which would mean a wrong r. */
static int zig_init(void) {
    double x[ZIG_LAYERS];
    const double fr = exp(-0.5 * ZIG_R * ZIG_R);
    const double v = ZIG_R * fr + sqrt(M_PI / 2.0) * erfc(ZIG_R / M_SQRT2);
    x[ZIG_LAYERS - 1] = ZIG_R;
    for (int i = ZIG_LAYERS - 1; i >= 2; i--) x[i - 1] = sqrt(-2.0 * log(v / x[i] + exp(-0.5 * x[i] * x[i])));
    x[0] = 0.0;
    const double q = v / fr;
    zig_k[0] = (uint64_t)ldexp(ZIG_R / q, 52);
    zig_w[0] = ldexp(q, -52);
    zig_f[0] = 1.0;
    for (int i = 1; i < ZIG_LAYERS; i++) {
        zig_k[i] = (uint64_t)ldexp(x[i - 1] / x[i], 52);
        zig_w[i] = ldexp(x[i], -52);
        zig_f[i] = exp(-0.5 * x[i] * x[i]);
    }
    return fabs(x[1] * (1.0 - zig_f[1]) - v) < 1e-9 * v;
}

static double zig_slow(Rng *g, uint64_t r);

/* One N(0, 1) deviate, from one 64-bit draw in 99% of calls: 8 bits pick the layer, 1 the sign, 52 the x. The
 * rare rest runs on a copy of the state, so that a caller's generator can live in registers. */
INLINE double normal(Rng *g) {
    const uint64_t r = next64(g);
    const int i = (int)(r & 0xff);
    const int64_t j = (int64_t)(r >> 12);
    if ((uint64_t)j < zig_k[i]) {                 /* the sign without a branch: bit 8 of r to bit 63 of x */
        double x = (double)j * zig_w[i];
        uint64_t bits;
        memcpy(&bits, &x, sizeof bits);
        bits ^= (r & 0x100) << 55;
        memcpy(&x, &bits, sizeof x);
        return x;
    }
    Rng copy = *g;
    const double x = zig_slow(&copy, r);
    *g = copy;
    return x;
}

/* The draw r missed its layer's rectangle: the tail or the wedge, then fresh draws until one is accepted. */
static double zig_slow(Rng *g, uint64_t r) {
    for (;;) {
        const int i = (int)(r & 0xff);
        const int64_t j = (int64_t)(r >> 12);
        const double sign = r & 0x100 ? -1.0 : 1.0;
        double x = (double)j * zig_w[i];
        if ((uint64_t)j < zig_k[i]) return sign * x;
        if (i == 0) {                   /* the tail beyond r (Marsaglia 1964): x = r + E₁/r with 2E₂ > (E₁/r)² */
            double xx, yy;
            do {
                xx = -log1p(-uniform(g)) / ZIG_R;
                yy = -log1p(-uniform(g));
            } while (yy + yy <= xx * xx);
            return sign * (ZIG_R + xx);
        }
        /* the wedge x_{i−1} ≤ x < x_i: accept if under the curve */
        if (zig_f[i] + uniform(g) * (zig_f[i - 1] - zig_f[i]) < exp(-0.5 * x * x)) return sign * x;
        r = next64(g);
    }
}

/* n deviates into z, the generator in registers. */
static void normals(Rng *g, double *z, Py_ssize_t n) {
    Rng local = *g;
    for (Py_ssize_t i = 0; i < n; i++) z[i] = normal(&local);
    *g = local;
}

/* ---- Poisson -------------------------------------------------------------------------------------------- */

#define SMALL_FACTORIALS 10
#define RECIPROCALS 64
static double factorial[SMALL_FACTORIALS];   /* k! for k < 10 */
static double reciprocal[RECIPROCALS];       /* 1/k for 0 < k < 64 */

/* Poisson(mean < 10) by inversion: sequential search from 0 (mean + 1 steps on average). The cap at 1000 ends the
 * search if rounding leaves the summed pmf just short of a uniform within 2⁻⁵³ of 1. */
static double poisson_inversion(Rng *g, double mean) {
    const double u = uniform(g);
    double p = exp(-mean), cdf = p;
    int k = 0;
    while (u >= cdf && k < 1000) {
        k++;
        p *= k < RECIPROCALS ? mean * reciprocal[k] : mean / k;
        cdf += p;
    }
    return k;
}

/* poisson_inversion on a copy of the state, so that a caller's generator can live in registers */
INLINE double poisson_small(Rng *g, double mean) {
    Rng copy = *g;
    const double k = poisson_inversion(&copy, mean);
    *g = copy;
    return k;
}

typedef struct { double omega, c0, c1, c2, c3, c; } PdHat;

/* Step P of PD: the constants of the normal cell probabilities q_k = ω e^{−x²/2} (c0 + c1x² + c2x⁴ + c3x⁶),
 * x = (k + ½ − μ)/√μ (Taylor series of the normal's integral over the cell), and of the Laplace hat. */
static PdHat pd_hat(double mean, double s) {
    PdHat h;
    const double b1 = 1.0 / (24.0 * mean), b2 = 0.3 * b1 * b1;
    h.omega = 1.0 / (sqrt(2.0 * M_PI) * s);
    h.c3 = b1 * b2 / 7.0;
    h.c2 = b2 - 15.0 * h.c3;
    h.c1 = b1 - 6.0 * b2 + 45.0 * h.c3;
    h.c0 = 1.0 - b1 + 3.0 * b2 - 15.0 * h.c3;
    h.c = 0.1069 / mean;
    return h;
}

/* Step F of PD: p_k = py·e^{px} (the Poisson pmf; Stirling's series to 1/(360k³) for k ≥ 10) and
 * q_k = fy·e^{fx} (the normal cell). */
static void pd_f(const PdHat *h, double mean, double s, double k, double *px, double *py, double *fx, double *fy) {
    const double difmuk = mean - k;
    if (k < SMALL_FACTORIALS) {
        *px = -mean;
        *py = pow(mean, k) / factorial[(int)k];
    } else {
        const double del = 1.0 / (12.0 * k) - 1.0 / (360.0 * k * k * k);
        *px = k * log1p(difmuk / k) - difmuk - del;
        *py = 1.0 / sqrt(2.0 * M_PI * k);
    }
    const double x = (0.5 - difmuk) / s, x2 = x * x;
    *fx = -0.5 * x2;
    *fy = h->omega * (((h->c3 * x2 + h->c2) * x2 + h->c1) * x2 + h->c0);
}

/* PD after steps N, I and S declined k (k < 0: the normal sample was negative), u being step S's uniform. */
static double pd_rest(Rng *g, double mean, double s, double k, double u) {
    double px, py, fx, fy;
    const PdHat h = pd_hat(mean, s);                                  /* step P */
    if (k >= 0.0) {                                                   /* step Q: accept with prob. p_k/q_k */
        pd_f(&h, mean, s, k, &px, &py, &fx, &fy);
        if (fy - u * fy <= py * exp(px - fx)) return k;
    }
    for (;;) {                                                        /* step E: t from the Laplace hat */
        const double e = -log1p(-uniform(g));
        const double v = 2.0 * uniform(g) - 1.0;
        const double t = 1.8 + (v < 0.0 ? -e : e);
        if (t <= -0.6744) continue;                                   /* pmf < normal cell there */
        k = floor(mean + s * t);
        pd_f(&h, mean, s, k, &px, &py, &fx, &fy);
        if (h.c * fabs(v) <= py * exp(px + e) - fy * exp(fx + e)) return k;   /* step H */
    }
}

/* Ahrens & Dieter's PD, mean ≥ 10, s = √mean, with z the N(0, 1) deviate of step N. Step S's uniform is drawn
 * whether needed or not, so that steps I and S make one well-predicted branch (accepting ~97% of draws). */
INLINE double poisson_pd(Rng *g, double mean, double s, double z) {
    const double g_n = mean + s * z;                                  /* step N */
    const double u = uniform(g);
    const double k = g_n >= 0.0 ? (double)(int64_t)g_n : -1.0;        /* ⌊g_n⌋, or −1 for a negative sample */
    const double d = mean - k;
    /* step I (k ≥ ⌊mean − 1.1484⌋: pmf ≥ normal cell there) or step S (squeeze) */
    if ((k >= 0.0) & ((k >= (double)(int64_t)(mean - 1.1484)) | (6.0 * mean * mean * u >= d * d * d))) return k;
    Rng copy = *g;
    const double r = pd_rest(&copy, mean, s, k, u);
    *g = copy;
    return r;
}

static double poisson(Rng *g, double mean) {
    return mean < 10.0 ? poisson_small(g, mean) : poisson_pd(g, mean, sqrt(mean), normal(g));
}

/* ---- the frame ------------------------------------------------------------------------------------------ */

typedef struct {
    Py_buffer view;
    char kind;      /* 'f' or 'd' */
    int held;
} Frame2D;

/* A Python exception raised while getting `what`'s buffer, re-raised naming it: TypeError (no buffer) stays,
 * the others (not contiguous, read-only: ValueError or BufferError) become ValueError. */
static int get_buffer(PyObject *obj, Py_buffer *view, int flags, const char *what) {
    if (PyObject_GetBuffer(obj, view, flags) == 0) return 0;
    PyObject *type, *value, *tb;
    PyErr_Fetch(&type, &value, &tb);
    PyObject *kind = PyErr_GivenExceptionMatches(type, PyExc_TypeError) ? PyExc_TypeError : PyExc_ValueError;
    PyObject *text = value ? PyObject_Str(value) : NULL;
    PyErr_Format(kind, "%s: %s", what, text ? PyUnicode_AsUTF8(text) : "no buffer");
    Py_XDECREF(text); Py_XDECREF(type); Py_XDECREF(value); Py_XDECREF(tb);
    return -1;
}

static char format_of(const Py_buffer *view) {
    const char *fmt = view->format ? view->format : "B";
    if (fmt[0] == '=' || fmt[0] == '<' || fmt[0] == '@') fmt++;
    return fmt[1] == '\0' ? fmt[0] : '?';
}

/* A (h, w) array of one of `kinds` ("f", "fd"). */
static int frame_open(PyObject *obj, Frame2D *f, Py_ssize_t h, Py_ssize_t w, const char *kinds, const char *what) {
    f->held = 0;
    if (get_buffer(obj, &f->view, PyBUF_STRIDES | PyBUF_FORMAT, what) < 0) return -1;
    f->held = 1;
    f->kind = format_of(&f->view);
    if (f->kind == '?' || !strchr(kinds, f->kind)) {
        PyErr_Format(PyExc_TypeError, "%s: must be %s, got buffer format '%s'", what,
                     kinds[1] ? "float32 or float64" : "float32", f->view.format ? f->view.format : "B");
        return -1;
    }
    if (f->view.ndim != 2 || f->view.shape[0] != h || f->view.shape[1] != w) {
        PyErr_Format(PyExc_ValueError, "%s: expected a (%zd, %zd) array like the output", what, h, w);
        return -1;
    }
    return 0;
}

static void frame_close(Frame2D *f) {
    if (f->held) PyBuffer_Release(&f->view);
    f->held = 0;
}

/* Row y as float32: a pointer into the array when it holds contiguous float32 rows, else converted into
 * scratch[0..w) (float64 values rounded to float32, as numpy's dtype=float32 casts). */
static const float *frame_row(const Frame2D *f, Py_ssize_t y, Py_ssize_t w, float *scratch) {
    const char *row = (const char *)f->view.buf + y * f->view.strides[0];
    const Py_ssize_t s = f->view.strides[1];
    Py_ssize_t x;
    if (f->kind == 'f') {
        if (s == 4) return (const float *)row;
        for (x = 0; x < w; x++) scratch[x] = *(const float *)(row + x * s);
    } else if (s == 8) {
        const double *p = (const double *)row;
        for (x = 0; x < w; x++) scratch[x] = (float)p[x];
    } else {
        for (x = 0; x < w; x++) scratch[x] = (float)*(const double *)(row + x * s);
    }
    return scratch;
}

typedef struct {
    Frame2D response, dark, lum;
    int lum_is_array;
    float lum_value;
    float exposure, photo_scale, read_var, cap, skew2, full_well, beta, gain, black, max_dn;
    double read_noise;
    uint64_t seed;
    unsigned short *out;
    Py_ssize_t h, w;
    Py_ssize_t bad_y, bad_x;     /* first pixel whose mean is NaN or negative where Poisson is drawn */
} Sensor;

/* v = √v, correctly rounded as sqrtf, four at a time (the compiler keeps sqrtf scalar for errno's sake). */
static void sqrt_row(float *v, Py_ssize_t n) {
    Py_ssize_t x = 0;
#if defined(__SSE2__)
    for (; x + 4 <= n; x += 4) _mm_storeu_ps(v + x, _mm_sqrt_ps(_mm_loadu_ps(v + x)));
#elif defined(__ARM_NEON) && defined(__aarch64__)
    for (; x + 4 <= n; x += 4) vst1q_f32(v + x, vsqrtq_f32(vld1q_f32(v + x)));
#endif
    for (; x < n; x++) v[x] = sqrtf(v[x]);
}

/* v = √v for float64, two at a time. */
static void sqrt_row_d(double *v, Py_ssize_t n) {
    Py_ssize_t x = 0;
#if defined(__SSE2__)
    for (; x + 2 <= n; x += 2) _mm_storeu_pd(v + x, _mm_sqrt_pd(_mm_loadu_pd(v + x)));
#elif defined(__ARM_NEON) && defined(__aarch64__)
    for (; x + 2 <= n; x += 2) vst1q_f64(v + x, vsqrtq_f64(vld1q_f64(v + x)));
#endif
    for (; x < n; x++) v[x] = sqrt(v[x]);
}

/* Per row of w pixels: float32 mean, sd, lum, charge; float64 z, z2, mu, s; int32 exact. */
#define WORK_BYTES_PER_PIXEL (4 * sizeof(float) + 4 * sizeof(double) + sizeof(int32_t))

/* Rows [y0, y1), one pass per step so that the arithmetic vectorises; `work` holds WORK_BYTES_PER_PIXEL·w bytes.
 * Row y's stream: w normals (the normal draws, which are also the Poisson draws' step-N normals), then, if
 * some pixels take Poisson, their read noise (one normal each) and the rest of their Poisson draws in order.
 * Returns 0, or -1 after a bad mean (its pixel in bad_y, bad_x). */
static int sensor_rows(Sensor *m, Py_ssize_t y0, Py_ssize_t y1, char *work) {
    const Py_ssize_t w = m->w;
    float *mean = (float *)work, *sd = mean + w, *lum = sd + w, *charge = lum + w;
    double *z = (double *)(charge + w), *z2 = z + w, *mu = z2 + w, *root = mu + w;
    int32_t *exact = (int32_t *)(root + w);
    const float rv = m->read_var, cap = m->cap, skew2 = m->skew2;
    for (Py_ssize_t y = y0; y < y1; y++) {
        Py_ssize_t x, j, n_exact = 0;
        Rng g;
        rng_seed(&g, m->seed, (uint64_t)y);
        /* mean = dark·t + (L·s)·response, capped: numpy's float32 operations in its order */
        const float *dark = frame_row(&m->dark, y, w, sd), *response = frame_row(&m->response, y, w, charge);
        const float t = m->exposure, scale = m->photo_scale;
        if (m->lum_is_array) {
            const float *l = frame_row(&m->lum, y, w, lum);
            for (x = 0; x < w; x++) mean[x] = dark[x] * t + (l[x] * scale) * response[x];
        } else {
            const float l = m->lum_value * scale;
            for (x = 0; x < w; x++) mean[x] = dark[x] * t + l * response[x];
        }
        /* which pixels' charge the normal N(mean, mean + σd²) cannot stand for (see sensor.electrons), and
         * whether a mean is NaN, or negative where Poisson is drawn */
        int bad = 0;
        for (x = 0; x < w; x++) {
            const float mu = mean[x] > cap ? cap : mean[x], var = mu + rv;
            float cube = var * var;
            cube *= var;
            cube *= skew2;
            const int32_t take = mu * mu > cube;
            bad |= (mu != mu) | (take & (mu < 0.0f));
            mean[x] = mu;
            sd[x] = var;
            exact[x] = take;
            n_exact += take;
        }
        if (bad) {
            for (x = 0; !(mean[x] != mean[x] || (exact[x] && mean[x] < 0.0f)); x++) {}
            m->bad_y = y; m->bad_x = x;
            return -1;
        }
        sqrt_row(sd, w);
        if (n_exact) {                          /* their columns, in order */
            for (x = 0, j = 0; x < w; x++) {
                const int32_t take = exact[x];
                exact[j] = (int32_t)x;
                j += take;
            }
        }
        normals(&g, z, w);
        for (x = 0; x < w; x++) charge[x] = (float)z[x] * sd[x] + mean[x];
        if (n_exact) {
            /* gathered: their means in float64, the square roots PD needs and their normals (z[j] ← z[x ≥ j]) */
            for (j = 0; j < n_exact; j++) {
                x = exact[j];
                mu[j] = root[j] = mean[x];
                z[j] = z[x];
            }
            sqrt_row_d(root, n_exact);
            const int noisy = m->read_noise > 0.0;
            if (noisy) normals(&g, z2, n_exact);
            Rng local = g;
            for (j = 0; j < n_exact; j++) {
                const double k = mu[j] < 10.0 ? poisson_small(&local, mu[j]) : poisson_pd(&local, mu[j], root[j], z[j]);
                float c = (float)k;
                if (noisy) c += (float)(m->read_noise * z2[j]);
                charge[exact[j]] = c;
            }
        }
        /* full-well clip, nonlinearity, DN = rint(black + K·e) clipped to the ADC: clipping before rounding
         * gives the same integers, and within 0 … 2¹⁶ adding and subtracting 1.5·2²³ rounds half to even */
        unsigned short *out = m->out + y * w;
        const float fw = m->full_well, beta = m->beta, k = m->gain, black = m->black, top = m->max_dn;
        if (beta != 0.0f)
            for (x = 0; x < w; x++) {
                const float c = charge[x] < fw ? charge[x] : fw;
                charge[x] = c * (1.0f - beta * (1.0f - c / fw));
            }
        else
            for (x = 0; x < w; x++) charge[x] = charge[x] < fw ? charge[x] : fw;
        for (x = 0; x < w; x++) {
            float dn = charge[x] * k;
            dn += black;
            dn = dn > 0.0f ? dn : 0.0f;
            dn = dn < top ? dn : top;
            dn = (dn + 12582912.0f) - 12582912.0f;
            out[x] = (unsigned short)(int)dn;
        }
    }
    return 0;
}

static void sensor_release(Sensor *m) {
    frame_close(&m->response); frame_close(&m->dark); frame_close(&m->lum);
}

/* read_rows(out, response, dark_e_s, luminance, exposure_s, photo_scale, read_noise_e, full_well_e,
 *           saturation_guard, max_skewness, nonlinearity_rel, gain_dn_per_e, black_level_dn, bit_depth,
 *           seed, y0, y1) */
static PyObject *py_read_rows(PyObject *self, PyObject *args) {
    PyObject *out_obj, *response, *dark, *lum;
    double exposure, photo_scale, read_noise, full_well, guard, skew, beta, gain, black;
    int bits;
    unsigned long long seed;
    Py_ssize_t y0, y1;
    Sensor m;
    Py_buffer out;
    char *work;
    int status;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOdddddddddiKnn", &out_obj, &response, &dark, &lum, &exposure, &photo_scale,
                          &read_noise, &full_well, &guard, &skew, &beta, &gain, &black, &bits, &seed, &y0, &y1))
        return NULL;
    memset(&m, 0, sizeof m);
    if (bits < 1 || bits > 16) return PyErr_Format(PyExc_ValueError, "bit_depth: must be 1 to 16, got %d", bits);
    if (!(read_noise >= 0.0) || !(full_well > 0.0))
        return PyErr_Format(PyExc_ValueError, "read_noise_e must be >= 0 and full_well_e > 0");
    if (get_buffer(out_obj, &out, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE | PyBUF_FORMAT, "out") < 0) return NULL;
    if (format_of(&out) != 'H' || out.ndim != 2) {
        PyErr_Format(PyExc_TypeError, "out: must be a 2-D uint16 array, got format '%s' and %d dimensions",
                     out.format ? out.format : "B", out.ndim);
        PyBuffer_Release(&out);
        return NULL;
    }
    m.h = out.shape[0];
    m.w = out.shape[1];
    m.out = (unsigned short *)out.buf;
    if (y0 < 0 || y1 > m.h || y0 > y1) {
        PyBuffer_Release(&out);
        return PyErr_Format(PyExc_ValueError, "rows [%zd, %zd) outside the output's %zd rows", y0, y1, m.h);
    }
    if (frame_open(response, &m.response, m.h, m.w, "f", "response") < 0 ||
        frame_open(dark, &m.dark, m.h, m.w, "f", "dark_e_s") < 0) goto fail;
    if (PyFloat_Check(lum) || PyLong_Check(lum)) {
        double v = PyFloat_AsDouble(lum);
        if (v == -1.0 && PyErr_Occurred()) goto fail;
        m.lum_value = (float)v;
    } else {
        if (frame_open(lum, &m.lum, m.h, m.w, "fd", "luminance") < 0) goto fail;
        m.lum_is_array = 1;
    }
    m.exposure = (float)exposure;
    m.photo_scale = (float)photo_scale;
    m.read_noise = read_noise;
    m.read_var = (float)(read_noise * read_noise);
    m.cap = (float)(guard * full_well);
    m.skew2 = (float)(skew * skew);
    m.full_well = (float)full_well;
    m.beta = (float)beta;
    m.gain = (float)gain;
    m.black = (float)black;
    m.max_dn = (float)((1 << bits) - 1);
    m.seed = (uint64_t)seed;
    work = malloc(WORK_BYTES_PER_PIXEL * (size_t)(m.w > 0 ? m.w : 1));
    if (!work) { PyErr_NoMemory(); goto fail; }
    Py_BEGIN_ALLOW_THREADS
    status = sensor_rows(&m, y0, y1, work);
    Py_END_ALLOW_THREADS
    free(work);
    if (status < 0) {
        PyErr_Format(PyExc_ValueError, "luminance: the mean charge of pixel (row %zd, column %zd) is negative or "
                     "not a number", m.bad_y, m.bad_x);
        goto fail;
    }
    sensor_release(&m);
    PyBuffer_Release(&out);
    Py_RETURN_NONE;
fail:
    sensor_release(&m);
    PyBuffer_Release(&out);
    return NULL;
}

/* ---- test entries: the samplers on their own ------------------------------------------------------------ */

static int open_doubles(PyObject *obj, Py_buffer *view) {
    if (get_buffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE | PyBUF_FORMAT, "out") < 0) return -1;
    if (format_of(view) != 'd') {
        PyBuffer_Release(view);
        PyErr_SetString(PyExc_TypeError, "out: must be a float64 array");
        return -1;
    }
    return 0;
}

static PyObject *py_standard_normal(PyObject *self, PyObject *args) {
    unsigned long long seed;
    PyObject *obj;
    Py_buffer view;
    (void)self;
    if (!PyArg_ParseTuple(args, "KO", &seed, &obj) || open_doubles(obj, &view) < 0) return NULL;
    double *out = view.buf;
    const Py_ssize_t n = view.len / 8;
    Py_BEGIN_ALLOW_THREADS
    Rng g;
    rng_seed(&g, (uint64_t)seed, 0);
    for (Py_ssize_t i = 0; i < n; i++) out[i] = normal(&g);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    Py_RETURN_NONE;
}

static PyObject *py_poisson(PyObject *self, PyObject *args) {
    unsigned long long seed;
    double mean;
    PyObject *obj;
    Py_buffer view;
    (void)self;
    if (!PyArg_ParseTuple(args, "KdO", &seed, &mean, &obj)) return NULL;
    if (!(mean >= 0.0 && mean < 1e15))
        return PyErr_Format(PyExc_ValueError, "mean: must be 0 to 1e15, got %R", PyTuple_GET_ITEM(args, 1));
    if (open_doubles(obj, &view) < 0) return NULL;
    double *out = view.buf;
    const Py_ssize_t n = view.len / 8;
    Py_BEGIN_ALLOW_THREADS
    Rng g;
    rng_seed(&g, (uint64_t)seed, 0);
    for (Py_ssize_t i = 0; i < n; i++) out[i] = poisson(&g, mean);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view);
    Py_RETURN_NONE;
}

static PyMethodDef METHODS[] = {
    {"read_rows", py_read_rows, METH_VARARGS,
     "read_rows(out, response, dark_e_s, luminance, exposure_s, photo_scale, read_noise_e, full_well_e,\n"
     "          saturation_guard, max_skewness, nonlinearity_rel, gain_dn_per_e, black_level_dn, bit_depth,\n"
     "          seed, y0, y1)\n"
     "Rows [y0, y1) of a raw frame into out (uint16, C-contiguous (H, W)); see rig.simulators.sensor.\n"
     "Row y's random numbers depend only on (seed, y). Releases the GIL."},
    {"standard_normal", py_standard_normal, METH_VARARGS,
     "standard_normal(seed, out)\nFill the float64 array out with N(0, 1) deviates of the ziggurat."},
    {"poisson", py_poisson, METH_VARARGS,
     "poisson(seed, mean, out)\nFill the float64 array out with Poisson(mean) deviates."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_sensor_kernel",
                                    "The compiled sensor read-out of rig.simulators.sensor (see SensorModel.read).",
                                    -1, METHODS, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__sensor_kernel(void) {
    if (!zig_init()) {
        PyErr_SetString(PyExc_ImportError, "_sensor_kernel: the ziggurat's tables do not close");
        return NULL;
    }
    factorial[0] = 1.0;
    for (int k = 1; k < SMALL_FACTORIALS; k++) factorial[k] = factorial[k - 1] * k;
    for (int k = 1; k < RECIPROCALS; k++) reciprocal[k] = 1.0 / k;
    return PyModule_Create(&MODULE);
}
