/* The simulated camera's rays on the lit sample (rig.simulators.camera.lit_view), compiled: one pass over
 * the pixels of a box.
 *
 * lit_view's geometry reduces every per-pixel quantity to an outer sum: the unnormalised ray d of the pixel
 * in row r and column c projects on a vector q as row_q[r] + col_q[c]. Python computes those row and column
 * terms (a few short vectors); this loop does per pixel what lit_view's numpy code does per array, the same
 * operations in the same order, so the two agree bit for bit: the approach d·n (a ray hits the front where
 * it is negative), t = −(o·n)/(d·n), the hit's GCS x and z and the lit test x² + z² ≤ r², then for a lit
 * pixel the ray in the SCS, the hit in sample coordinates and ωo = d/−|d|. Lit pixels are written in row-major
 * order, as numpy's boolean indexing lists them.
 *
 * Inputs through the buffer protocol (no numpy headers): `rows` float64 (TERMS, height) and `cols` float64
 * (TERMS, width), both C-contiguous, holding per term k: 0 the approach d·n, 1 and 2 the GCS x and z, 3–5
 * the SCS x, y, z, 6 the squared length (sy² by row, sx² + f² by column); outputs `lit` bool (height, width),
 * `xy` float64 (≥ N, 2) and `wo` float64 (≥ N, 3), C-contiguous. The GIL is released.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#define TERMS 7

enum { APPROACH, GCS_X, GCS_Z, SCS_X, SCS_Y, SCS_Z, LENGTH2 };

typedef struct {
    Py_buffer view;
    int held;
} Buffer;

/* A C-contiguous buffer of `format` ('d' or '?') and `ndim` dimensions; shape[0] == first if first ≥ 0. */
static int open_buffer(PyObject *obj, Buffer *b, char format, int ndim, Py_ssize_t first, int writable,
                       const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) return -1;
    b->held = 1;
    const char *fmt = b->view.format ? b->view.format : "B";
    if (fmt[0] == '=' || fmt[0] == '<' || fmt[0] == '@') fmt++;
    if (fmt[0] != format || fmt[1] != '\0' || b->view.ndim != ndim || (first >= 0 && b->view.shape[0] != first)) {
        PyErr_Format(PyExc_ValueError, "%s: expected a C-contiguous %d-D %s array%s", what, ndim,
                     format == 'd' ? "float64" : "bool", first >= 0 ? " of the documented shape" : "");
        return -1;
    }
    return 0;
}

static void release(Buffer *b, int n) {
    for (int i = 0; i < n; i++)
        if (b[i].held) PyBuffer_Release(&b[i].view);
}

/* lit_rays(rows, cols, height, origin_x, origin_z, radius2, start_x, start_y, lit, xy, wo) -> N lit pixels */
static PyObject *lit_rays(PyObject *Py_UNUSED(module), PyObject *args) {
    PyObject *objs[5];
    double height, ox, oz, r2, start_x, start_y;
    if (!PyArg_ParseTuple(args, "OOddddddOOO", &objs[0], &objs[1], &height, &ox, &oz, &r2, &start_x, &start_y,
                          &objs[2], &objs[3], &objs[4]))
        return NULL;
    Buffer b[5];
    memset(b, 0, sizeof b);
    int failed = open_buffer(objs[0], &b[0], 'd', 2, TERMS, 0, "rows") < 0
                 || open_buffer(objs[1], &b[1], 'd', 2, TERMS, 0, "cols") < 0;
    Py_ssize_t h = failed ? 0 : b[0].view.shape[1], w = failed ? 0 : b[1].view.shape[1];
    failed = failed || open_buffer(objs[2], &b[2], '?', 2, h, 1, "lit") < 0
             || open_buffer(objs[3], &b[3], 'd', 2, -1, 1, "xy") < 0
             || open_buffer(objs[4], &b[4], 'd', 2, -1, 1, "wo") < 0;
    if (!failed && (b[2].view.shape[1] != w || b[3].view.shape[1] != 2 || b[4].view.shape[1] != 3
                    || b[3].view.shape[0] < h * w || b[4].view.shape[0] < h * w)) {
        PyErr_SetString(PyExc_ValueError, "lit must be (height, width), xy (≥ height·width, 2), wo (≥ height·width, 3)");
        failed = 1;
    }
    if (failed) {
        release(b, 5);
        return NULL;
    }
    const double *rows = b[0].view.buf, *cols = b[1].view.buf;
    char *lit = b[2].view.buf;
    double *xy = b[3].view.buf, *wo = b[4].view.buf;
    Py_ssize_t n = 0;
    Py_BEGIN_ALLOW_THREADS
    memset(lit, 0, (size_t)(h * w));
    for (Py_ssize_t r = 0; r < h; r++) {
        const double *row = rows + r, *col = cols;       /* term k: row[k·h], col[k·w + c] */
        for (Py_ssize_t c = 0; c < w; c++) {
            double approach = row[APPROACH * h] + col[APPROACH * w + c];
            if (!(approach < 0)) continue;                    /* the ray misses the front (or runs along it) */
            double t = -height / approach;
            double x = (row[GCS_X * h] + col[GCS_X * w + c]) * t + ox;
            double z = (row[GCS_Z * h] + col[GCS_Z * w + c]) * t + oz;
            if (!(x * x + z * z <= r2)) continue;              /* outside the beam */
            lit[r * w + c] = 1;
            double length = -sqrt(row[LENGTH2 * h] + col[LENGTH2 * w + c]);
            double dx = row[SCS_X * h] + col[SCS_X * w + c], dy = row[SCS_Y * h] + col[SCS_Y * w + c];
            double dz = row[SCS_Z * h] + col[SCS_Z * w + c];
            xy[2 * n] = dx * t + start_x;
            xy[2 * n + 1] = dy * t + start_y;
            wo[3 * n] = dx / length;
            wo[3 * n + 1] = dy / length;
            wo[3 * n + 2] = dz / length;
            n++;
        }
    }
    Py_END_ALLOW_THREADS
    release(b, 5);
    return PyLong_FromSsize_t(n);
}

static PyMethodDef METHODS[] = {
    {"lit_rays", lit_rays, METH_VARARGS,
     "lit_rays(rows, cols, height, origin_x, origin_z, radius2, start_x, start_y, lit, xy, wo) -> N: the lit "
     "pixels of a box from the row and column terms of its rays (see simulators/_view_kernel.c)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_view_kernel",
                                    "The simulated camera's rays on the lit sample, compiled.", -1, METHODS,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__view_kernel(void) { return PyModule_Create(&MODULE); }
