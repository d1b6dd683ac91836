/* The HDR merge of rig.physics.hdr.merge_exposures on a band of rows, compiled: one pass over the frames.
 *
 * Same estimator, weights and outputs as the numpy block merge (see merge_exposures' Notes); here every
 * pass of the re-weighting runs on one row at a time, so the row's working arrays stay in the CPU's L1/L2
 * cache and each loop below is a plain loop over pixels that the compiler vectorises (no -ffast-math: IEEE
 * float32 arithmetic, the same results on any x86-64 or ARM machine). The GIL is released, so the Python
 * side merges bands of rows on every core.
 *
 * Inputs are read through the buffer protocol (no numpy headers): 2-D frames of uint16 ('H'), float32 ('f')
 * or float64 ('d'), any strides. Per exposure k: the mean frame, the frame to test for saturation (the
 * maximum over a stack; the mean frame itself for one frame) and the mean dark, plus the per-exposure
 * constants 1/t, a, b, c and the saturation threshold. Outputs: float32 rate, var_rate, var_dark, uint8
 * n_used, bool saturated and clipped, (H, W) C-contiguous; all but the rate may be None (a saved image needs
 * the rate alone, and writing the others would double the memory traffic).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdlib.h>
#include <string.h>

#define MAX_EXPOSURES 16

typedef struct {
    Py_buffer view;
    char kind;      /* 'H', 'f' or 'd' */
    int held;
} Frame2D;

static int frame_open(PyObject *obj, Frame2D *f, Py_ssize_t h, Py_ssize_t w, const char *what) {
    f->held = 0;
    if (PyObject_GetBuffer(obj, &f->view, PyBUF_STRIDES | PyBUF_FORMAT) < 0) return -1;
    f->held = 1;
    const char *fmt = f->view.format ? f->view.format : "B";
    if (fmt[0] == '=' || fmt[0] == '<' || fmt[0] == '@') fmt++;
    f->kind = fmt[0];
    if (fmt[1] != '\0' || (f->kind != 'H' && f->kind != 'f' && f->kind != 'd')) {
        PyErr_Format(PyExc_TypeError, "%s: frames must be uint16, float32 or float64, got format '%s'", what,
                     f->view.format);
        return -1;
    }
    if (f->view.ndim != 2 || f->view.shape[0] != h || f->view.shape[1] != w) {
        PyErr_Format(PyExc_ValueError, "%s: expected a (%zd, %zd) frame", what, h, w);
        return -1;
    }
    return 0;
}

static void frame_close(Frame2D *f) {
    if (f->held) PyBuffer_Release(&f->view);
    f->held = 0;
}

/* Row y of a frame as float32 into out[0..w). */
static void frame_row(const Frame2D *f, Py_ssize_t y, Py_ssize_t w, float *out) {
    const char *row = (const char *)f->view.buf + y * f->view.strides[0];
    Py_ssize_t s = f->view.strides[1];
    Py_ssize_t x;
    switch (f->kind) {
    case 'H':
        if (s == 2) { const unsigned short *p = (const unsigned short *)row; for (x = 0; x < w; x++) out[x] = (float)p[x]; }
        else for (x = 0; x < w; x++) out[x] = (float)*(const unsigned short *)(row + x * s);
        break;
    case 'f':
        if (s == 4) memcpy(out, row, (size_t)w * sizeof(float));
        else for (x = 0; x < w; x++) out[x] = *(const float *)(row + x * s);
        break;
    default:
        for (x = 0; x < w; x++) out[x] = (float)*(const double *)(row + x * s);
    }
}

/* Saturation flags of row y: frame value >= threshold (compared in the frame's own type, as numpy does). */
static void frame_saturated(const Frame2D *f, Py_ssize_t y, Py_ssize_t w, double threshold, unsigned char *out) {
    const char *row = (const char *)f->view.buf + y * f->view.strides[0];
    Py_ssize_t s = f->view.strides[1];
    Py_ssize_t x;
    switch (f->kind) {
    case 'H': {
        /* integer frames come with an integer threshold (hdr._threshold_for), here within 0 … 65536 */
        int t = threshold < 0 ? 0 : threshold > 65536 ? 65536 : (int)threshold;
        if (s == 2) { const unsigned short *q = (const unsigned short *)row; for (x = 0; x < w; x++) out[x] = q[x] >= t; }
        else for (x = 0; x < w; x++) out[x] = *(const unsigned short *)(row + x * s) >= t;
        break;
    }
    case 'f': {
        float t = (float)threshold;
        if (s == 4) { const float *q = (const float *)row; for (x = 0; x < w; x++) out[x] = q[x] >= t; }
        else for (x = 0; x < w; x++) out[x] = *(const float *)(row + x * s) >= t;
        break;
    }
    default:
        for (x = 0; x < w; x++) out[x] = *(const double *)(row + x * s) >= threshold;
    }
}

typedef struct {
    int n;
    Frame2D mean[MAX_EXPOSURES], peak[MAX_EXPOSURES], dark[MAX_EXPOSURES];
    double inv_t[MAX_EXPOSURES], a[MAX_EXPOSURES], b[MAX_EXPOSURES], c[MAX_EXPOSURES], threshold[MAX_EXPOSURES];
    int shortest, longest, passes;
    Py_buffer out[6];       /* rate, var_rate, var_dark, n_used, saturated, clipped */
    int out_held;
} Merge;

static const char *OUT_NAMES[6] = {"rate", "var_rate", "var_dark", "n_used", "saturated", "clipped"};

#if defined(__GNUC__)
#define ALWAYS_INLINE static inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE static inline
#endif

/* The estimate of one row, every pass in registers: X̂ = Σ wₖ rₖ / Σ wₖ with wₖ = scaleₖ/bₖ, then REWEIGHT
 * passes with wₖ = scaleₖ/(max(X̂, 0) + bₖ); var = 1/Σ wₖ and var_dark = Σ wₖ² cₖ · var² from the last weights.
 * `rate` and `scale` hold n rows of w. Inlined with a constant n. */
ALWAYS_INLINE void reweigh(const int n, const int passes, const Py_ssize_t w, const float *rate, const float *scale,
                           const float *b, const float *c, float *out_rate, float *out_var, float *out_dark) {
    for (Py_ssize_t x = 0; x < w; x++) {
        float wsum = 0.0f, num = 0.0f, dark = 0.0f, merged;
        for (int k = 0; k < n; k++) {
            float wk = scale[k * w + x] / b[k];
            wsum += wk;
            num += wk * rate[k * w + x];
        }
        merged = num / wsum;
        for (int p = 1; p <= passes; p++) {
            float signal = merged > 0.0f ? merged : 0.0f;            /* max(X̂, 0) of the previous pass */
            wsum = 0.0f; num = 0.0f; dark = 0.0f;
            for (int k = 0; k < n; k++) {
                float wk = scale[k * w + x] / (signal + b[k]);
                wsum += wk;
                num += wk * rate[k * w + x];
                dark += wk * wk * c[k];
            }
            if (p < passes) merged = num / wsum;
        }
        if (passes == 0)
            for (int k = 0; k < n; k++) { float wk = scale[k * w + x] / b[k]; dark += wk * wk * c[k]; }
        float var = 1.0f / wsum;
        out_rate[x] = passes ? num * var : merged;
        out_var[x] = var;
        out_dark[x] = dark * var * var;
    }
}

/* Row y of output k, or its scratch row when the output is not wanted (None). */
static void *out_row(const Merge *m, int k, Py_ssize_t y, Py_ssize_t w, void *scratch) {
    return m->out[k].buf ? (char *)m->out[k].buf + y * w * m->out[k].itemsize : scratch;
}

/* reweigh for a single exposure, whose weight cancels: X̂ = r at every pass, so var = 1/w = (max(r, 0) + b)/a
 * and var_dark = c exactly; the passes would give the same to float32 rounding, with five divisions a pixel. */
static void single(const Py_ssize_t w, const float *rate, const float *scale, const float b, const float c,
                   float *out_rate, float *out_var, float *out_dark) {
    for (Py_ssize_t x = 0; x < w; x++) {
        float signal = rate[x] > 0.0f ? rate[x] : 0.0f;
        out_rate[x] = rate[x];
        out_var[x] = (signal + b) / scale[x];
        out_dark[x] = c;
    }
}

/* Merge rows [y0, y1); `work` holds (2n + 1)·w floats and (n + 1)·w bytes; `spare` 2·w floats and then 3·w
 * bytes, the rows of the outputs not wanted (an allocation of its own: pointers into `work` would keep gcc
 * from vectorising the passes, 2.4× slower). */
static void merge_rows(const Merge *m, Py_ssize_t y0, Py_ssize_t y1, Py_ssize_t w, float *work, unsigned char *flags,
                       float *spare) {
    const int n = m->n;
    float *rate = work, *scale = work + n * w, *tmp = work + 2 * n * w;
    unsigned char *spare_flags = (unsigned char *)(spare + 2 * w);
    float b[MAX_EXPOSURES], c[MAX_EXPOSURES];
    unsigned char *sat = flags, *clipped = flags + n * w;
    Py_ssize_t x, y;
    int k;
    for (k = 0; k < n; k++) { b[k] = (float)m->b[k]; c[k] = (float)m->c[k]; }
    for (y = y0; y < y1; y++) {
        for (x = 0; x < w; x++) clipped[x] = 1;
        for (k = 0; k < n; k++) {
            unsigned char *s = sat + k * w;
            frame_saturated(&m->peak[k], y, w, m->threshold[k], s);
            for (x = 0; x < w; x++) clipped[x] &= s[x];
        }
        for (k = 0; k < n; k++) {
            float *r = rate + k * w, *sc = scale + k * w;
            const unsigned char *s = sat + k * w;
            const float inv_t = (float)m->inv_t[k], a = (float)m->a[k];
            frame_row(&m->mean[k], y, w, r);
            frame_row(&m->dark[k], y, w, tmp);
            for (x = 0; x < w; x++) r[x] = (r[x] - tmp[x]) * inv_t;
            /* aₖ where usable, else 0; clipped pixels keep the shortest exposure's rate (clipped ⊆ saturated) */
            const unsigned char keep = k == m->shortest;
            for (x = 0; x < w; x++) sc[x] = a * (float)(1 - (s[x] & (unsigned char)(1 - (clipped[x] & keep))));
        }
        {
            float *out_rate = out_row(m, 0, y, w, NULL);
            float *out_var = out_row(m, 1, y, w, spare);
            float *out_dark = out_row(m, 2, y, w, spare + w);
            unsigned char *out_n = out_row(m, 3, y, w, spare_flags);
            unsigned char *out_sat = out_row(m, 4, y, w, spare_flags + w);
            unsigned char *out_clip = out_row(m, 5, y, w, spare_flags + 2 * w);
            const unsigned char *longest = sat + m->longest * w;
            /* constant counts (rig's 2 passes, up to 4 exposures): the loops over exposures and passes unroll
             * and the loop over pixels vectorises */
            switch (n == 1 ? 1 : m->passes == 2 ? n : 0) {
            case 1: single(w, rate, scale, b[0], c[0], out_rate, out_var, out_dark); break;
            case 2: reweigh(2, 2, w, rate, scale, b, c, out_rate, out_var, out_dark); break;
            case 3: reweigh(3, 2, w, rate, scale, b, c, out_rate, out_var, out_dark); break;
            case 4: reweigh(4, 2, w, rate, scale, b, c, out_rate, out_var, out_dark); break;
            default: reweigh(n, m->passes, w, rate, scale, b, c, out_rate, out_var, out_dark);
            }
            for (x = 0; x < w; x++) {
                out_sat[x] = longest[x];
                out_clip[x] = clipped[x];
            }
            for (x = 0; x < w; x++) out_n[x] = (unsigned char)n;
            for (k = 0; k < n; k++) {
                const unsigned char *s = sat + k * w;
                for (x = 0; x < w; x++) out_n[x] -= s[x];
            }
        }
    }
}

static void merge_release(Merge *m) {
    int k;
    for (k = 0; k < m->n; k++) { frame_close(&m->mean[k]); frame_close(&m->peak[k]); frame_close(&m->dark[k]); }
    for (k = 0; k < m->out_held; k++)
        if (m->out[k].buf) PyBuffer_Release(&m->out[k]);
    m->out_held = 0;
}

static int doubles(PyObject *seq, int n, double *out, const char *what) {
    PyObject *fast = PySequence_Fast(seq, what);
    if (!fast) return -1;
    if (PySequence_Fast_GET_SIZE(fast) != n) {
        Py_DECREF(fast);
        PyErr_Format(PyExc_ValueError, "%s: need one value per exposure", what);
        return -1;
    }
    for (int k = 0; k < n; k++) {
        out[k] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(fast, k));
        if (out[k] == -1.0 && PyErr_Occurred()) { Py_DECREF(fast); return -1; }
    }
    Py_DECREF(fast);
    return 0;
}

/* merge_rows(means, peaks, darks, thresholds, inv_t, a, b, c, shortest, longest, passes, outputs, y0, y1) */
static PyObject *py_merge_rows(PyObject *self, PyObject *args) {
    PyObject *means, *peaks, *darks, *thresholds, *inv_t, *a, *b, *c, *outputs;
    int shortest, longest, passes;
    Py_ssize_t y0, y1;
    Merge m;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOiiiOnn", &means, &peaks, &darks, &thresholds, &inv_t, &a, &b, &c,
                          &shortest, &longest, &passes, &outputs, &y0, &y1))
        return NULL;
    memset(&m, 0, sizeof m);
    Py_ssize_t n = PySequence_Size(means);
    if (n < 1 || n > MAX_EXPOSURES || PySequence_Size(peaks) != n || PySequence_Size(darks) != n) {
        if (!PyErr_Occurred())
            PyErr_Format(PyExc_ValueError, "need 1 to %d exposures, with one peak and one dark frame each", MAX_EXPOSURES);
        return NULL;
    }
    if (PySequence_Size(outputs) != 6) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "need 6 output arrays");
        return NULL;
    }
    m.n = 0;
    m.shortest = shortest; m.longest = longest; m.passes = passes;
    if (shortest < 0 || shortest >= n || longest < 0 || longest >= n || passes < 0) {
        PyErr_SetString(PyExc_ValueError, "shortest/longest must index an exposure and passes be >= 0");
        return NULL;
    }
    Py_ssize_t h = -1, w = -1;
    for (int k = 0; k < 6; k++) {
        PyObject *o = PySequence_GetItem(outputs, k);
        if (!o) { merge_release(&m); return NULL; }
        if (o == Py_None && k > 0) {            /* not wanted: its rows go to scratch (merge_rows) */
            Py_DECREF(o);
            m.out[k].buf = NULL;
            m.out_held = k + 1;
            continue;
        }
        int got = PyObject_GetBuffer(o, &m.out[k], PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE | PyBUF_FORMAT);
        Py_DECREF(o);
        if (got < 0) { merge_release(&m); return NULL; }
        m.out_held = k + 1;
        Py_ssize_t item = k < 3 ? 4 : 1;
        if (m.out[k].ndim != 2 || m.out[k].itemsize != item || (h >= 0 && (m.out[k].shape[0] != h || m.out[k].shape[1] != w))) {
            PyErr_Format(PyExc_ValueError, "output %s: wrong shape or item size", OUT_NAMES[k]);
            merge_release(&m);
            return NULL;
        }
        h = m.out[k].shape[0]; w = m.out[k].shape[1];
    }
    if (y0 < 0 || y1 > h || y0 > y1) {
        PyErr_SetString(PyExc_ValueError, "rows out of range");
        merge_release(&m);
        return NULL;
    }
    for (int k = 0; k < n; k++) {
        PyObject *objs[3] = {PySequence_GetItem(means, k), PySequence_GetItem(peaks, k), PySequence_GetItem(darks, k)};
        Frame2D *dst[3] = {&m.mean[k], &m.peak[k], &m.dark[k]};
        static const char *what[3] = {"frame", "saturation frame", "dark"};
        m.n = k + 1;
        for (int j = 0; j < 3; j++) {
            int bad = !objs[j] || frame_open(objs[j], dst[j], h, w, what[j]) < 0;
            if (bad) {
                for (int i = 0; i < 3; i++) Py_XDECREF(objs[i]);
                merge_release(&m);
                return NULL;
            }
        }
        for (int i = 0; i < 3; i++) Py_DECREF(objs[i]);
    }
    if (doubles(thresholds, (int)n, m.threshold, "thresholds") < 0 || doubles(inv_t, (int)n, m.inv_t, "inv_t") < 0 ||
        doubles(a, (int)n, m.a, "a") < 0 || doubles(b, (int)n, m.b, "b") < 0 || doubles(c, (int)n, m.c, "c") < 0) {
        merge_release(&m);
        return NULL;
    }
    float *work = malloc(sizeof(float) * (size_t)(2 * n + 1) * (size_t)(w > 0 ? w : 1));
    unsigned char *flags = malloc((size_t)(n + 1) * (size_t)(w > 0 ? w : 1));
    float *spare = malloc((2 * sizeof(float) + 3) * (size_t)(w > 0 ? w : 1));
    if (!work || !flags || !spare) {
        free(work); free(flags); free(spare);
        merge_release(&m);
        return PyErr_NoMemory();
    }
    Py_BEGIN_ALLOW_THREADS
    merge_rows(&m, y0, y1, w, work, flags, spare);
    Py_END_ALLOW_THREADS
    free(work); free(flags); free(spare);
    merge_release(&m);
    Py_RETURN_NONE;
}

static PyMethodDef METHODS[] = {
    {"merge_rows", py_merge_rows, METH_VARARGS,
     "merge_rows(means, peaks, darks, thresholds, inv_t, a, b, c, shortest, longest, passes, outputs, y0, y1)\n"
     "Merge rows [y0, y1) of the exposures into the six outputs (see rig.physics.hdr); all but the rate may be\n"
     "None (not wanted). Releases the GIL."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_merge_kernel",
                                    "The compiled HDR merge of rig.physics.hdr (see its merge_exposures).", -1, METHODS,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__merge_kernel(void) { return PyModule_Create(&MODULE); }
