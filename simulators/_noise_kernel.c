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
 * point lie in the block of nodes spanned by the points' cells, and a table over that block holds the
 * values of the nodes the points use. Only those are computed: on a frame the glint's 4-D block is several
 * times larger than the set of corners its pixels touch, because the half vector and the position on the
 * sample change together across the image. Where the block is too large (points scattered far apart),
 * each corner is computed where it is needed.
 *
 * A node's value is a long chain of dependent operations (the hash, ndtri, exp): computed as the points
 * came to need them, behind a branch the CPU could not predict, they ran one at a time. So the work is
 * done in passes over arrays, loops whose iterations are independent and do not branch on the data, with
 * the chains of several nodes (or points) side by side in the code for the CPU to overlap.
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
/* The table is used when it holds at most this many nodes per point: its values are touched only where
 * used and its marks (a byte per node) are read 8 at a time, so that a block far larger than its points (a
 * grazing view, whose pixels lie far apart along the sample) still costs less than computing every
 * corner ... */
#define TABLE_NODES_PER_POINT 1024
/* ... and at most this many nodes in all (128 MB of address space; table indices fit 32 bits). */
#define TABLE_MAX_NODES (1 << 24)
/* Nodes valued side by side. */
#define BATCH 8

/* Functions taking constant counts first (axes, nodes side by side, the fastest axis of a table) are
 * inlined for each, so that their loops unroll. */
#define INLINE static inline __attribute__((always_inline))

static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* Cephes' polevl and p1evl (leading coefficient 1, not stored) at x[0..n) into r. */
INLINE void polevl(const int n, const double *x, const double *c, int degree, double *r) {
    for (int j = 0; j < n; j++) r[j] = c[0];
    for (int i = 1; i <= degree; i++)
        for (int j = 0; j < n; j++) r[j] = r[j] * x[j] + c[i];
}

INLINE void p1evl(const int n, const double *x, const double *c, int degree, double *r) {
    for (int j = 0; j < n; j++) r[j] = x[j] + c[0];
    for (int i = 1; i < degree; i++)
        for (int j = 0; j < n; j++) r[j] = r[j] * x[j] + c[i];
}

/* Cephes ndtri, x with Φ(x) = y for 0 < y < 1, in its two branches: a rational function of y near the
 * centre, of sqrt(−2 log y) in the tails. Cephes first folds y > 1 − e⁻² to 1 − y (exact), then tests
 * y > e⁻²; a folded y is never above e⁻² (1 − fl(1 − e⁻²) is e⁻² exactly), so the centre is
 * e⁻² < y ≤ 1 − e⁻² of the unfolded y, and nodes can be sorted by branch before either runs. */
static const double NDTRI_EXPM2 = 0.13533528323661269189;    /* exp(-2) */

static int ndtri_in_centre(double y) { return (y > NDTRI_EXPM2) & !(y > 1.0 - NDTRI_EXPM2); }

/* x[j] = ndtri(y[j]) for y[0..n) in the centre. */
INLINE void ndtri_centre(const int n, const double *y, double *x) {
    static const double s2pi = 2.50662827463100050242E0;
    static const double P0[5] = {-5.99633501014107895267E1, 9.80010754185999661536E1,
                                 -5.66762857469070293439E1, 1.39312609387279679503E1,
                                 -1.23916583867381258016E0};
    static const double Q0[8] = {1.95448858338141759834E0, 4.67627912898881538453E0,
                                 8.63602421390890590575E1, -2.25462687854119370527E2,
                                 2.00260212380060660359E2, -8.20372256168333339912E1,
                                 1.59056225126211695515E1, -1.18331621121330003142E0};
    double t[BATCH], t2[BATCH], p[BATCH], q[BATCH];
    for (int j = 0; j < n; j++) {
        t[j] = y[j] - 0.5;
        t2[j] = t[j] * t[j];
    }
    polevl(n, t2, P0, 4, p);
    p1evl(n, t2, Q0, 8, q);
    for (int j = 0; j < n; j++) x[j] = (t[j] + t[j] * (t2[j] * p[j] / q[j])) * s2pi;
}

/* x[j] = ndtri(y[j]) for y[0..n) in the tails. */
INLINE void ndtri_tail(const int n, const double *y, double *x) {
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
    double s[BATCH], z[BATCH], p[BATCH], q[BATCH];
    int upper[BATCH];
    for (int j = 0; j < n; j++) {
        upper[j] = y[j] > 1.0 - NDTRI_EXPM2;                    /* folded: x > 0 */
        s[j] = sqrt(-2.0 * log(upper[j] ? 1.0 - y[j] : y[j]));
        z[j] = 1.0 / s[j];
    }
    polevl(n, z, P1, 8, p);
    p1evl(n, z, Q1, 8, q);
    for (int j = 0; j < n; j++)
        if (s[j] >= 8.0) {                                      /* y < e⁻³²: hardly ever */
            polevl(1, &z[j], P2, 8, &p[j]);
            p1evl(1, &z[j], Q2, 8, &q[j]);
        }
    for (int j = 0; j < n; j++) {
        double x0 = s[j] - log(s[j]) / s[j];
        double x1 = z[j] * p[j] / q[j];
        x[j] = upper[j] ? x0 - x1 : -(x0 - x1);
    }
}

typedef struct {
    int n;                 /* axes */
    uint64_t seeded;       /* mix64(seed): the hash chain's start */
    double sigma, shift;   /* log-normal: exp(sigma·z − shift) */
} Lattice;

/* A node's value (texture.noise_lattice) in two steps, so that nodes can be sorted by ndtri's branch in
 * between: the uniform in (0, 1) at the end of its hash chain (texture.hash_uniform) ... */
static double uniform(uint64_t h) { return ((double)(h >> 11) + 0.5) * 0x1p-53; }

/* ... and the log-normal quantiles of n uniforms (texture.lognormal_unit_mean), all in ndtri's centre or
 * all not. */
INLINE void lognormal(const int n, const int centre, const Lattice *L, const double *u, double *v) {
    double z[BATCH];
    if (centre)
        ndtri_centre(n, u, z);
    else
        ndtri_tail(n, u, z);
    for (int j = 0; j < n; j++) v[j] = exp(L->sigma * z[j] - L->shift);
}

/* The value of integer node node[0..axes). */
INLINE double node_value(const int axes, const Lattice *L, const int64_t *node) {
    uint64_t h = L->seeded;
    for (int k = 0; k < axes; k++) h = mix64(h ^ (uint64_t)node[k]);
    double u = uniform(h), v;
    if (ndtri_in_centre(u))
        lognormal(1, 1, L, &u, &v);
    else
        lognormal(1, 0, L, &u, &v);
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

/* floor(c), exactly (|c| < 2^62), without libm (whose floor is a call on baseline x86-64). */
static int64_t floor_int(double c) {
    int64_t t = (int64_t)c;
    return t - ((double)t > c);
}

/* Points are done two at a time, side by side in the two lanes of an SSE2 (or NEON) register: GCC's vector
 * extension, whose operators work lane by lane as on doubles (the same operations, so the same results). */
typedef double v2df __attribute__((vector_size(2 * sizeof(double))));
typedef int64_t v2di __attribute__((vector_size(2 * sizeof(double))));   /* comparisons: −1 where true */

/* Points i and i + 1, or i twice for the last of an odd count. */
static void pair_at(Py_ssize_t *at, Py_ssize_t i, Py_ssize_t i1) {
    at[0] = i;
    at[1] = i + 1 < i1 ? i + 1 : i;
}

static v2df coordinates(const Buffer *b, const Py_ssize_t *at) {
    return (v2df){coordinate(b, at[0]), coordinate(b, at[1])};
}

/* floor(c) for |c| < 2^51, in both lanes, without libm: c ± 2^52 lies where doubles are 1 apart, so
 * (c ± 2^52) ∓ 2^52 is c rounded to an integer, exactly; less 1 where that rose above c. */
static v2df floor_near(v2df c) {
    const v2di sign = {INT64_MIN, INT64_MIN};
    const v2df big = {0x1p52, 0x1p52}, one = {1.0, 1.0};
    v2df signed_big = (v2df)(((v2di)c & sign) | (v2di)big);
    v2df rounded = (c + signed_big) - signed_big;
    return rounded - (v2df)((v2di)one & (v2di)(rounded > c));
}

static v2df smoothstep(v2df t) { return t * t * (3.0 - 2.0 * t); }

/* The multilinear blend of corner values v (overwritten; corner c is +1 along axis k where bit k of c is
 * set) with weights w: texture.blend. */
INLINE v2df blend(const int axes, v2df *v, const v2df *w) {
    for (int k = 0, m = 1 << axes; k < axes; k++, m >>= 1)      /* pairs (2i, 2i+1) differ along axis k */
        for (int i = 0; i < m / 2; i++) v[i] = (v[2 * i + 1] - v[2 * i]) * w[k] + v[2 * i];
    return v[0];
}

/* Points [i0, i1) without a table: each corner computed where it is needed. */
INLINE void noise_per_corner(const int axes, const Buffer *coords, const Lattice *L, double *out,
                             Py_ssize_t i0, Py_ssize_t i1) {
    for (Py_ssize_t i = i0; i < i1; i += 2) {
        Py_ssize_t at[2];
        int64_t cell[2][MAX_AXES], node[MAX_AXES];
        v2df v[1 << MAX_AXES], w[MAX_AXES];
        pair_at(at, i, i1);
        for (int k = 0; k < axes; k++) {
            v2df c = coordinates(&coords[k], at);
            for (int j = 0; j < 2; j++) cell[j][k] = floor_int(c[j]);
            w[k] = smoothstep(c - (v2df){(double)cell[0][k], (double)cell[1][k]});
        }
        for (int c = 0; c < 1 << axes; c++)
            for (int j = 0; j < 2; j++) {
                for (int k = 0; k < axes; k++) node[k] = cell[j][k] + ((c >> k) & 1);
                v[c][j] = node_value(axes, L, node);
            }
        v2df r = blend(axes, v, w);
        out[at[0]] = r[0];
        out[at[1]] = r[1];
    }
}

/* The block of nodes a table covers: from `low`, `shape` nodes along each axis, axis order[0] fastest
 * (stride 1), then the others in their order (index strides `stride`); corner c of a cell is `offset[c]`
 * after its corner 0. The longest axis is the fastest: a frame's glint uses runs of nodes along the
 * sample's x, where the half vector's axes span a few nodes, so that the values in use lie on half as many
 * cache lines and memory pages as with axis 0 fastest.
 *
 * The nodes share the start of their hash chain, through their first axes: it is computed once for each
 * combination of the first `prefix` axes' coordinates, the first `prefix_nodes` indices (so those must be
 * the fastest axes: the prefix is empty or takes the fastest in), and each node's chain goes on from
 * there. A combination costs a mix64 or so, as does each axis after the prefix for each node hashed,
 * so the prefix takes all the axes it can while they have fewer combinations than there are points (a
 * frame's glint: the half vector's two and the sample's x, leaving 1 mix64 of 4 per node). */
typedef struct {
    int64_t low[MAX_AXES], shape[MAX_AXES], stride[MAX_AXES], offset[1 << MAX_AXES];
    int order[MAX_AXES];
    int prefix;
    int64_t prefix_nodes;
    double inverse_shape[MAX_AXES], inverse_prefix_nodes;      /* 1 / each, rounded */
} Block;

/* a / b for table indices a < 2^24, b ≤ 2^24, from inverse = 1 / b rounded: the product is within a few
 * 2^-53 (relative) of the exact quotient, whose fractional part is either 0 or at least 1/b ≥ 2^-24, so it
 * truncates to the quotient or, for an exact one, 1 below; the remainder tells which. (Dividing, exact in
 * double too, does not pipeline.) */
static int64_t quotient(int64_t a, int64_t b, double inverse) {
    int64_t q = (int64_t)((double)a * inverse);
    return q + (a - q * b >= b);
}

/* The hash chains through the prefix axes, H[0..B->prefix_nodes), their coordinates x counted in the
 * order of the table's indices. */
static void hash_prefix(const Lattice *L, const Block *B, uint64_t *H) {
    int64_t x[MAX_AXES] = {0};
    for (int64_t r = 0; r < B->prefix_nodes; r++) {
        uint64_t h = L->seeded;
        for (int k = 0; k < B->prefix; k++) h = mix64(h ^ (uint64_t)(B->low[k] + x[k]));
        H[r] = h;
        for (int i = 0; i < B->prefix && ++x[B->order[i]] == B->shape[B->order[i]]; i++) x[B->order[i]] = 0;
    }
}

/* The uniforms hashed from the nodes at table indices index[0..BATCH), from their chains H through the
 * prefix axes: an index is a number in mixed radix, B->prefix_nodes then the shape of each later axis in
 * the table's order. */
INLINE void block_uniforms(const int axes, const Block *B, const uint64_t *H, const uint32_t *index,
                           double *u) {
    uint64_t h[BATCH];
    int64_t node[BATCH][MAX_AXES], rest[BATCH];
    for (int j = 0; j < BATCH; j++) {
        rest[j] = quotient(index[j], B->prefix_nodes, B->inverse_prefix_nodes);
        h[j] = H[index[j] - rest[j] * B->prefix_nodes];
    }
    for (int i = 0; i < axes; i++)
        if (i >= B->prefix)
            for (int j = 0; j < BATCH; j++) {
                int k = B->order[i];
                int64_t next = i + 1 < axes ? quotient(rest[j], B->shape[k], B->inverse_shape[k]) : 0;
                node[j][k] = B->low[k] + rest[j] - next * B->shape[k];
                rest[j] = next;
            }
    for (int k = 0; k < axes; k++)
        if (k >= B->prefix)
            for (int j = 0; j < BATCH; j++) h[j] = mix64(h[j] ^ (uint64_t)node[j][k]);
    for (int j = 0; j < BATCH; j++) u[j] = uniform(h[j]);
}

/* Lists of nodes are done BATCH at a time, the last batch repeating the last node. */
static void pad(uint32_t *list, size_t n) {
    for (int q = 0; n && q < BATCH; q++) list[n + q] = list[n - 1];
}

/* Points at[0..2): the corners of their cells marked in `marks` (corners c and c + 2^fastest, neighbours,
 * at once), and the index of their corner 0 kept in bases[at − i0]. A point in the cell of the point
 * before (a frame's glint has 3 or 4 in a row) marks nothing new: skipping it pays for the branch. */
INLINE void mark_corners(const int axes, const int fastest, const Buffer *coords, const Py_ssize_t *at,
                         const Block *B, unsigned char *marks, uint32_t *bases, Py_ssize_t i0,
                         int64_t *last) {
    static const unsigned char both[2] = {1, 1};
    int64_t base[2] = {0, 0};
    for (int k = 0; k < axes; k++)
        for (int j = 0; j < 2; j++)
            base[j] += (floor_int(coordinate(&coords[k], at[j])) - B->low[k]) * B->stride[k];
    for (int j = 0; j < 2; j++) {
        if (base[j] != *last)
            for (int c = 0; c < 1 << axes; c++)
                if (!(c >> fastest & 1)) memcpy(marks + base[j] + B->offset[c], both, 2);
        *last = base[j];
        bases[at[j] - i0] = (uint32_t)base[j];
    }
}

/* Points at[0..2) blended from the table, their cells' floor found again in both lanes at once. */
INLINE void blend_corners(const int axes, const int fastest, const Buffer *coords, const Py_ssize_t *at,
                          const Block *B, const double *table, const uint32_t *bases, Py_ssize_t i0,
                          double *out) {
    v2df v[1 << MAX_AXES], w[MAX_AXES];
    for (int k = 0; k < axes; k++) {
        v2df c = coordinates(&coords[k], at);
        w[k] = smoothstep(c - floor_near(c));
    }
    for (int c = 0; c < 1 << axes; c++)
        if (!(c >> fastest & 1)) {                    /* corners c and c + 2^fastest, neighbours */
            const double *first = table + bases[at[0] - i0] + B->offset[c];
            const double *second = table + bases[at[1] - i0] + B->offset[c];
            v[c] = (v2df){first[0], second[0]};
            v[c | 1 << fastest] = (v2df){first[1], second[1]};
        }
    v2df r = blend(axes, v, w);
    out[at[0]] = r[0];
    out[at[1]] = r[1];
}

/* The passes over points [i0, i1): pairs i, i + 1 (so that their addresses step), then an odd last point
 * twice. */
INLINE void mark_points(const int axes, const int fastest, const Buffer *coords, const Block *B,
                        unsigned char *marks, uint32_t *bases, Py_ssize_t i0, Py_ssize_t i1) {
    int64_t last = -1;
    Py_ssize_t i = i0;
    for (; i + 1 < i1; i += 2) {
        Py_ssize_t at[2] = {i, i + 1};
        mark_corners(axes, fastest, coords, at, B, marks, bases, i0, &last);
    }
    if (i < i1) {
        Py_ssize_t at[2] = {i, i};
        mark_corners(axes, fastest, coords, at, B, marks, bases, i0, &last);
    }
}

INLINE void blend_points(const int axes, const int fastest, const Buffer *coords, const Block *B,
                         const double *table, const uint32_t *bases, Py_ssize_t i0, Py_ssize_t i1,
                         double *out) {
    Py_ssize_t i = i0;
    for (; i + 1 < i1; i += 2) {
        Py_ssize_t at[2] = {i, i + 1};
        blend_corners(axes, fastest, coords, at, B, table, bases, i0, out);
    }
    if (i < i1) {
        Py_ssize_t at[2] = {i, i};
        blend_corners(axes, fastest, coords, at, B, table, bases, i0, out);
    }
}

/* Points [i0, i1) through a table of the values in block B, in passes:
 * 1. mark the corners of the points' cells in `marks` (a byte per node, zeroed, and 8 more), keeping the
 *    index of each point's corner 0 in `bases` (one per point);
 * 2. list the nodes marked, 8 at a time, in `todo` (room for all plus BATCH);
 * 3. hash them from the prefix chains `H` (the uniform kept in `table` meanwhile) and sort them by
 *    ndtri's branch, the centre's kept in `todo` and the tails' moved to `tail` (as much room);
 * 4. compute their values, BATCH side by side;
 * 5. blend the points' corners.
 * The passes over the points take the table's fastest axis as a constant. */
INLINE void noise_with_table(const int axes, const Buffer *coords, const Lattice *L, double *out,
                             Py_ssize_t i0, Py_ssize_t i1, const Block *B, unsigned char *marks,
                             uint32_t *bases, uint32_t *todo, uint32_t *tail, uint64_t *H, double *table) {
    switch (B->order[0]) {
    case 0: mark_points(axes, 0, coords, B, marks, bases, i0, i1); break;
    case 1: if (axes > 1) mark_points(axes, 1, coords, B, marks, bases, i0, i1); break;
    case 2: if (axes > 2) mark_points(axes, 2, coords, B, marks, bases, i0, i1); break;
    default: if (axes > 3) mark_points(axes, 3, coords, B, marks, bases, i0, i1); break;
    }
    const int64_t nodes = B->stride[B->order[axes - 1]] * B->shape[B->order[axes - 1]];
    size_t used = 0;
    for (int64_t index = 0; index < nodes; index += 8) {
        uint64_t any;
        memcpy(&any, marks + index, sizeof any);
        if (any) {
            unsigned char in_use[8];
            memcpy(in_use, &any, sizeof in_use);
            for (int t = 0; t < 8; t++) {
                todo[used] = (uint32_t)(index + t);
                used += in_use[t];
            }
        }
    }
    pad(todo, used);
    hash_prefix(L, B, H);
    size_t centre = 0, tails = 0;
    for (size_t j = 0; j < used; j += BATCH) {
        uint32_t index[BATCH];
        double u[BATCH];
        for (int q = 0; q < BATCH; q++) index[q] = todo[j + q];
        block_uniforms(axes, B, H, index, u);
        for (int q = 0; q < BATCH; q++) {
            int listed = j + q < used, in_centre = ndtri_in_centre(u[q]);
            table[index[q]] = u[q];
            todo[centre] = index[q];                     /* centre <= j + q: an entry already read */
            tail[tails] = index[q];
            centre += listed & in_centre;
            tails += listed & !in_centre;
        }
    }
    pad(todo, centre);
    pad(tail, tails);
    for (size_t j = 0; j < centre; j += BATCH) {
        double u[BATCH], v[BATCH];
        for (int q = 0; q < BATCH; q++) u[q] = table[todo[j + q]];
        lognormal(BATCH, 1, L, u, v);
        for (int q = 0; q < BATCH; q++) table[todo[j + q]] = v[q];
    }
    for (size_t j = 0; j < tails; j += BATCH) {
        double u[BATCH], v[BATCH];
        for (int q = 0; q < BATCH; q++) u[q] = table[tail[j + q]];
        lognormal(BATCH, 0, L, u, v);
        for (int q = 0; q < BATCH; q++) table[tail[j + q]] = v[q];
    }
    switch (B->order[0]) {
    case 0: blend_points(axes, 0, coords, B, table, bases, i0, i1, out); break;
    case 1: if (axes > 1) blend_points(axes, 1, coords, B, table, bases, i0, i1, out); break;
    case 2: if (axes > 2) blend_points(axes, 2, coords, B, table, bases, i0, i1, out); break;
    default: if (axes > 3) blend_points(axes, 3, coords, B, table, bases, i0, i1, out); break;
    }
}

/* The range [lo, hi] of each coordinate over points [i0, i1) (two at a time, so that the minima and
 * maxima are chains side by side); 0 if one is not finite (or beyond 2^62). */
INLINE int extent(const int axes, const Buffer *coords, Py_ssize_t i0, Py_ssize_t i1, double *lo, double *hi) {
    double low[MAX_AXES][2], high[MAX_AXES][2];
    int finite = 1;
    for (int k = 0; k < axes; k++)
        for (int j = 0; j < 2; j++) {
            low[k][j] = INFINITY;
            high[k][j] = -INFINITY;
        }
    for (Py_ssize_t i = i0, at[2]; i < i1; i += 2) {
        pair_at(at, i, i1);
        for (int k = 0; k < axes; k++)
            for (int j = 0; j < 2; j++) {
                double c = coordinate(&coords[k], at[j]);
                finite &= fabs(c) < 0x1p62;                 /* false for NaN and ±inf too */
                low[k][j] = c < low[k][j] ? c : low[k][j];
                high[k][j] = c > high[k][j] ? c : high[k][j];
            }
    }
    for (int k = 0; k < axes; k++) {
        lo[k] = low[k][0] < low[k][1] ? low[k][0] : low[k][1];
        hi[k] = high[k][0] > high[k][1] ? high[k][0] : high[k][1];
    }
    return finite;
}

/* Value noise at points [i0, i1) into out, for `axes` axes; 0 if a coordinate is not finite (or beyond
 * 2^62). */
INLINE int noise_points(const int axes, const Buffer *coords, const Lattice *L, double *out, Py_ssize_t i0,
                        Py_ssize_t i1) {
    double lo[MAX_AXES], hi[MAX_AXES];
    if (i1 <= i0) return 1;
    if (!extent(axes, coords, i0, i1, lo, hi)) return 0;
    /* the block [floor(lo), floor(hi) + 1] per axis; the table's blending takes coordinates under 2^51 */
    double nodes = 1.0;
    int near = 1;
    for (int k = 0; k < axes; k++) {
        nodes *= floor(hi[k]) - floor(lo[k]) + 2.0;
        near &= fabs(lo[k]) < 0x1p51 && fabs(hi[k]) < 0x1p51;
    }
    unsigned char *marks = NULL;
    uint32_t *bases = NULL, *todo = NULL, *tail = NULL;
    uint64_t *H = NULL;
    double *table = NULL;
    if (near && nodes <= (double)TABLE_NODES_PER_POINT * (double)(i1 - i0) && nodes <= TABLE_MAX_NODES) {
        Block B;
        int fastest = 0;                                    /* the longest axis (the first of equals) */
        for (int k = 0; k < axes; k++) {
            B.low[k] = (int64_t)floor(lo[k]);
            B.shape[k] = (int64_t)floor(hi[k]) - B.low[k] + 2;
            B.inverse_shape[k] = 1.0 / (double)B.shape[k];
            fastest = B.shape[k] > B.shape[fastest] ? k : fastest;
        }
        B.order[0] = fastest;
        for (int k = 0, i = 1; k < axes; k++)
            if (k != fastest) B.order[i++] = k;
        for (int i = 0, stride = 1; i < axes; stride *= B.shape[B.order[i++]]) B.stride[B.order[i]] = stride;
        for (int c = 0; c < (1 << axes); c++) {             /* corner c's table index from its cell's */
            B.offset[c] = 0;
            for (int k = 0; k < axes; k++) B.offset[c] += ((c >> k) & 1) * B.stride[k];
        }
        B.prefix = 0;
        B.prefix_nodes = 1;
        for (int64_t p = 1, combinations = 1; p <= axes && (combinations *= B.shape[p - 1]) <= i1 - i0; p++)
            if (p > fastest) {
                B.prefix = (int)p;
                B.prefix_nodes = combinations;
            }
        B.inverse_prefix_nodes = 1.0 / (double)B.prefix_nodes;
        /* the lists have room for every node the points can use: allocated, not touched, beyond that */
        size_t room = (size_t)fmin(nodes, (double)(1 << axes) * (double)(i1 - i0)) + BATCH;
        marks = calloc((size_t)nodes + 8, 1);
        bases = malloc((size_t)(i1 - i0) * sizeof(uint32_t));
        todo = malloc(room * sizeof(uint32_t));
        tail = malloc(room * sizeof(uint32_t));
        H = malloc((size_t)B.prefix_nodes * sizeof(uint64_t));
        table = malloc((size_t)nodes * sizeof(double));
        if (marks && bases && todo && tail && H && table)
            noise_with_table(axes, coords, L, out, i0, i1, &B, marks, bases, todo, tail, H, table);
    }
    if (!(marks && bases && todo && tail && H && table))  /* too large a block, far out, or no memory */
        noise_per_corner(axes, coords, L, out, i0, i1);
    free(marks);
    free(bases);
    free(todo);
    free(tail);
    free(H);
    free(table);
    return 1;
}

/* Value noise at points [i0, i1) into out; 0 if a coordinate is not finite (or beyond 2^62). */
static int noise(const Buffer *coords, const Lattice *L, double *out, Py_ssize_t i0, Py_ssize_t i1) {
    switch (L->n) {
    case 1: return noise_points(1, coords, L, out, i0, i1);
    case 2: return noise_points(2, coords, L, out, i0, i1);
    case 3: return noise_points(3, coords, L, out, i0, i1);
    default: return noise_points(4, coords, L, out, i0, i1);
    }
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
    finite = noise(bufs, &L, (double *)bufs[MAX_AXES].view.buf, start, stop);
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
