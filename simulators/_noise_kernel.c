/* Value noise of rig.simulators.texture, compiled: the sample's static grains and glints on a full frame.
 *
 * The same function as texture.value_noise in numpy, value for value: each point's cell is the floor of its
 * lattice coordinates, its 2^n corner values are log-normal quantiles (mean 1, standard deviation
 * `contrast`) of a uniform hashed from the seed and the corner's integer coordinates (SplitMix64's
 * finaliser, as texture.hash_uniform), and they are blended multilinearly with smoothstep weights, axis 0
 * first (as texture.blend). The inverse normal CDF is Cephes' ndtri (S. L. Moshier, Cephes Math Library,
 * 1984-2000), the one scipy.special.ndtri uses, with its coefficients; results agree with the numpy
 * version to the last bit or two of exp and log.
 *
 * Points of one image are dense on the lattice, so a lattice value is computed once: the corners of every
 * point lie in the block of nodes spanned by the points' cells, and a table over that block (zero: not
 * yet computed; a value is always positive) is filled as points need its nodes. Only the nodes used are
 * hashed: on a frame the glint's 4-D block is several times larger than the set of corners its pixels
 * touch, because the half vector and the position on the sample change together across the image. Where
 * the block is too large (points scattered far apart), each corner is hashed where it is needed.
 *
 * Coordinates are read through the buffer protocol (1-D float64, any stride; no numpy headers); the
 * output is a writable C-contiguous float64 buffer of the same length. The GIL is released.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define MAX_AXES 4
/* The table is used when it holds at most this many nodes per point: it is allocated zeroed (calloc), so
 * only the memory pages of nodes in use are ever touched, and a block far larger than its points (a grazing
 * view, whose pixels lie far apart along the sample) still costs less than hashing every corner ... */
#define TABLE_NODES_PER_POINT 1024
/* ... and at most this many nodes in all (128 MB of address space). */
#define TABLE_MAX_NODES (1 << 24)

static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static double polevl(double x, const double *c, int n) {
    double r = c[0];
    for (int i = 1; i <= n; i++) r = r * x + c[i];
    return r;
}

static double p1evl(double x, const double *c, int n) {      /* leading coefficient 1, not stored */
    double r = x + c[0];
    for (int i = 1; i < n; i++) r = r * x + c[i];
    return r;
}

/* Cephes ndtri: x with Φ(x) = y, for 0 < y < 1. */
static double ndtri(double y) {
    static const double s2pi = 2.50662827463100050242E0;
    static const double expm2 = 0.13533528323661269189;    /* exp(-2) */
    static const double P0[5] = {-5.99633501014107895267E1, 9.80010754185999661536E1,
                                 -5.66762857469070293439E1, 1.39312609387279679503E1,
                                 -1.23916583867381258016E0};
    static const double Q0[8] = {1.95448858338141759834E0, 4.67627912898881538453E0,
                                 8.63602421390890590575E1, -2.25462687854119370527E2,
                                 2.00260212380060660359E2, -8.20372256168333339912E1,
                                 1.59056225126211695515E1, -1.18331621121330003142E0};
    static const double P1[9] = {4.05544892305962419923E0, 3.15251094599893866154E1,
                                 5.71628192246421288162E1, 4.40805073893200834700E1,
                                 1.46849561928858024014E1, 2.18663306850790267539E0,
                                 -1.40256079171354495875E-1, -3.50424626827848203418E-2,
                                 -8.57456785154685413611E-4};
    static const double Q1[8] = {1.57799883256466749731E1, 4.53907635128879210584E1,
                                 4.13172038254672030440E1, 1.50425385692907503408E1,
                                 2.50464946208309415979E0, -1.42182922854787788574E-1,
                                 -3.80806407691578277194E-2, -9.33259480895457427372E-4};
    static const double P2[9] = {3.23774891776946035970E0, 6.91522889068984211695E0,
                                 3.93881025292474443415E0, 1.33303460815807542389E0,
                                 2.01485389549179081538E-1, 1.23716634817820021358E-2,
                                 3.01581553508235416007E-4, 2.65806974686737550832E-6,
                                 6.23974539184983293730E-9};
    static const double Q2[8] = {6.02427039364742014255E0, 3.67983563856160859403E0,
                                 1.37702099489081330271E0, 2.16236993594496635890E-1,
                                 1.34204006088543189037E-2, 3.28014464682127739104E-4,
                                 2.89247864745380683936E-6, 6.79019408009981274425E-9};
    int negate = 1;
    if (y > 1.0 - expm2) {
        y = 1.0 - y;
        negate = 0;
    }
    if (y > expm2) {
        y -= 0.5;
        double y2 = y * y;
        return (y + y * (y2 * polevl(y2, P0, 4) / p1evl(y2, Q0, 8))) * s2pi;
    }
    double x = sqrt(-2.0 * log(y));
    double x0 = x - log(x) / x;
    double z = 1.0 / x;
    double x1 = x < 8.0 ? z * polevl(z, P1, 8) / p1evl(z, Q1, 8) : z * polevl(z, P2, 8) / p1evl(z, Q2, 8);
    x = x0 - x1;
    return negate ? -x : x;
}

typedef struct {
    int n;                 /* axes */
    uint64_t seeded;       /* mix64(seed): the hash chain's start */
    double sigma, shift;   /* log-normal: exp(sigma·z − shift) */
} Lattice;

/* The lattice value at integer node (nodes[0..n)): texture.noise_lattice. */
static double node_value(const Lattice *L, const int64_t *node) {
    uint64_t h = L->seeded;
    for (int k = 0; k < L->n; k++) h = mix64(h ^ (uint64_t)node[k]);
    double u = ((double)(h >> 11) + 0.5) * 0x1p-53;
    return exp(L->sigma * ndtri(u) - L->shift);
}

/* The value at corner c of `cell` (+1 along axis k where bit k of c is set), stored at `known` if not NULL. */
static double corner_value(const Lattice *L, const int64_t *cell, int c, double *known) {
    int64_t node[MAX_AXES];
    for (int k = 0; k < L->n; k++) node[k] = cell[k] + ((c >> k) & 1);
    double v = node_value(L, node);
    if (known) *known = v;
    return v;
}

typedef struct {
    Py_buffer view;
    int held;
} Buffer;

static void release(Buffer *b, int count) {
    for (int i = 0; i < count; i++)
        if (b[i].held) PyBuffer_Release(&b[i].view);
}

static int open_vector(PyObject *obj, Buffer *b, int writable, Py_ssize_t *n, const char *what) {
    int flags = writable ? (PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE | PyBUF_FORMAT) : (PyBUF_STRIDES | PyBUF_FORMAT);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) return -1;
    b->held = 1;
    const char *fmt = b->view.format ? b->view.format : "B";
    if (fmt[0] == '=' || fmt[0] == '<' || fmt[0] == '@') fmt++;
    if (fmt[0] != 'd' || fmt[1] != '\0' || b->view.ndim != 1) {
        PyErr_Format(PyExc_TypeError, "%s must be a 1-D float64 array", what);
        return -1;
    }
    if (*n >= 0 && b->view.shape[0] != *n) {
        PyErr_Format(PyExc_ValueError, "%s has %zd values, the coordinates %zd", what, b->view.shape[0], *n);
        return -1;
    }
    *n = b->view.shape[0];
    return 0;
}

static double coordinate(const Buffer *b, Py_ssize_t i) {
    return *(const double *)((const char *)b->view.buf + i * b->view.strides[0]);
}

static double smoothstep(double t) { return t * t * (3.0 - 2.0 * t); }

/* Points [i0, i1) with `axes` axes, their lattice values from `table` (NULL: hashed per corner); inlined
 * for each axis count, so that the loops over axes and corners unroll. */
static inline __attribute__((always_inline)) void
blend_points(const int axes, const Buffer *coords, const Lattice *L, double *table, const int64_t *low,
             const int64_t *offset, const int64_t *stride, double *out, Py_ssize_t i0, Py_ssize_t i1) {
    const int corners = 1 << axes;
    for (Py_ssize_t i = i0; i < i1; i++) {
        double v[1 << MAX_AXES], w[MAX_AXES];
        int64_t cell[MAX_AXES], base = 0;
        for (int k = 0; k < axes; k++) {
            double c = coordinate(&coords[k], i);
            int64_t t = (int64_t)c;                       /* floor(c), exactly (|c| < 2^62), without libm */
            cell[k] = t - ((double)t > c);
            double f = (double)cell[k];
            w[k] = smoothstep(c - f);
            base += table ? (cell[k] - low[k]) * stride[k] : 0;
        }
        for (int c = 0; c < corners; c++) {
            double *known = table ? &table[base + offset[c]] : NULL;
            v[c] = known && *known != 0.0 ? *known : corner_value(L, cell, c, known);
        }
        for (int k = 0, m = corners; k < axes; k++, m >>= 1)     /* pairs (2j, 2j+1) differ along axis k */
            for (int j = 0; j < m / 2; j++) v[j] = (v[2 * j + 1] - v[2 * j]) * w[k] + v[2 * j];
        out[i] = v[0];
    }
}

/* Value noise at points [i0, i1) into out; 0 if a coordinate is not finite (or beyond 2^62). */
static int noise_points(const Buffer *coords, const Lattice *L, double *out, Py_ssize_t i0, Py_ssize_t i1) {
    const int axes = L->n;
    double lo[MAX_AXES], hi[MAX_AXES];
    int finite = 1;
    for (int k = 0; k < axes; k++) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
        for (Py_ssize_t i = i0; i < i1; i++) {
            double c = coordinate(&coords[k], i);
            finite &= isfinite(c) && fabs(c) < 0x1p62;
            lo[k] = c < lo[k] ? c : lo[k];
            hi[k] = c > hi[k] ? c : hi[k];
        }
    }
    if (!finite || i1 <= i0) return finite;
    /* the block [floor(lo), floor(hi) + 1] per axis, axis 0 fastest: the glint's half-vector axes span a few
     * nodes, so a point's corners share cache lines */
    int64_t low[MAX_AXES], stride[MAX_AXES], offset[1 << MAX_AXES];
    double nodes = 1.0;
    for (int k = 0; k < axes; k++) {
        low[k] = (int64_t)floor(lo[k]);
        stride[k] = (int64_t)nodes;
        nodes *= floor(hi[k]) - floor(lo[k]) + 2.0;
    }
    double *table = NULL;
    if (nodes <= (double)TABLE_NODES_PER_POINT * (double)(i1 - i0) && nodes <= TABLE_MAX_NODES)
        table = calloc((size_t)nodes, sizeof(double));           /* NULL (no memory): hash per corner */
    for (int c = 0; c < (1 << axes); c++) {                 /* corner c's table index from its cell's */
        offset[c] = 0;
        for (int k = 0; k < axes; k++) offset[c] += ((c >> k) & 1) * stride[k];
    }
    switch (axes) {
    case 1: blend_points(1, coords, L, table, low, offset, stride, out, i0, i1); break;
    case 2: blend_points(2, coords, L, table, low, offset, stride, out, i0, i1); break;
    case 3: blend_points(3, coords, L, table, low, offset, stride, out, i0, i1); break;
    default: blend_points(4, coords, L, table, low, offset, stride, out, i0, i1); break;
    }
    free(table);
    return 1;
}

/* value_noise(coords, contrast, seed, out, start, stop): see the module comment. Points [start, stop) only,
 * with a table of their own, so that threads can share a long list of points. */
static PyObject *value_noise(PyObject *Py_UNUSED(module), PyObject *args) {
    PyObject *coords, *out_obj;
    double contrast;
    unsigned long long seed;
    Py_ssize_t start, stop;
    if (!PyArg_ParseTuple(args, "OdKOnn", &coords, &contrast, &seed, &out_obj, &start, &stop)) return NULL;
    PyObject *seq = PySequence_Fast(coords, "coords must be a sequence of arrays");
    if (!seq) return NULL;
    Py_ssize_t n_axes = PySequence_Fast_GET_SIZE(seq);
    if (n_axes < 1 || n_axes > MAX_AXES) {
        Py_DECREF(seq);
        return PyErr_Format(PyExc_ValueError, "value noise takes 1 to %d axes, got %zd", MAX_AXES, n_axes);
    }
    Buffer bufs[MAX_AXES + 1];
    memset(bufs, 0, sizeof bufs);
    Py_ssize_t n = -1;
    int failed = 0;
    for (int k = 0; k < n_axes && !failed; k++)
        failed = open_vector(PySequence_Fast_GET_ITEM(seq, k), &bufs[k], 0, &n, "a coordinate") < 0;
    if (!failed) failed = open_vector(out_obj, &bufs[MAX_AXES], 1, &n, "out") < 0;
    Py_DECREF(seq);
    if (!failed && (start < 0 || stop > n || start > stop)) {
        PyErr_Format(PyExc_ValueError, "points [%zd, %zd) are not within the %zd given", start, stop, n);
        failed = 1;
    }
    if (failed) {
        release(bufs, MAX_AXES + 1);
        return NULL;
    }
    double sigma = sqrt(log1p(contrast * contrast));
    Lattice L = {(int)n_axes, mix64((uint64_t)seed), sigma, sigma * sigma / 2};
    int finite;
    Py_BEGIN_ALLOW_THREADS
    finite = noise_points(bufs, &L, (double *)bufs[MAX_AXES].view.buf, start, stop);
    Py_END_ALLOW_THREADS
    release(bufs, MAX_AXES + 1);
    if (!finite) return PyErr_Format(PyExc_ValueError, "value noise needs finite lattice coordinates under 2**62");
    Py_RETURN_NONE;
}

static PyMethodDef METHODS[] = {
    {"value_noise", value_noise, METH_VARARGS,
     "value_noise(coords, contrast, seed, out, start, stop): value noise of mean 1 at points [start, stop) (coords: "
     "1 to 4 1-D float64 arrays of lattice coordinates), into out (float64, contiguous)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_noise_kernel",
                                    "Value noise of rig.simulators.texture, compiled.", -1, METHODS};

PyMODINIT_FUNC PyInit__noise_kernel(void) { return PyModule_Create(&MODULE); }
