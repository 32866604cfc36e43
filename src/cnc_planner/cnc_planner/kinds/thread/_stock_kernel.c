/* Whether the tool's tip is ever inside the stock over the thread: ThreadCycle._cuts_stock.
 *
 * The thread's search tries hundreds of air paths per plan, each checked at every servo
 * instant from the previous pass's exit to the join; in numpy each check cost a dozen
 * calls on a hundred instants. Here x and z are evaluated from their ruckig pieces
 * (ruckig_piece.h, each held at its end) instant by instant, and the check stops at the
 * first instant inside. The comparisons and the surface are _cuts_stock's numpy ones, in
 * the same order (setup.py: -ffp-contract=off), so the verdict is the same
 * (test_thread_cutting.py compares the two on every air path of the shipped threads).
 */
#include "../../kernel_buffers.h"
#include "../../ruckig_piece.h"

enum { Z_ROWS, Z_STARTS, Z_LO, Z_HI, X_ROWS, X_STARTS, X_LO, X_HI, TS, ARRAYS };
static const char *const NAMES[ARRAYS] = {"z_rows", "z_starts", "z_lo", "z_hi", "x_rows", "x_starts", "x_lo",
                                          "x_hi", "ts"};

/* Whether the pieces of one axis (rows, starts, lo, hi from ``first``) cover the instants
 * [0, n) one after the other, as ThreadCycle._pieces gives them; else the error is set. */
static int covers(const Py_buffer *v, int first, Py_ssize_t n)
{
    const Py_buffer *rows = &v[first], *starts = &v[first + 1], *lo = &v[first + 2], *hi = &v[first + 3];
    const Py_ssize_t pieces = starts->shape[0];
    if (rows->ndim != 2 || rows->shape[0] != pieces || rows->shape[1] != ROW || rows->strides[1] != sizeof(double)
        || starts->ndim != 1 || lo->ndim != 1 || hi->ndim != 1 || lo->shape[0] != pieces || hi->shape[0] != pieces) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd rows of %d and their starts, lo and hi", NAMES[first],
                     pieces, ROW);
        return 0;
    }
    Py_ssize_t next = 0;
    for (Py_ssize_t k = 0; k < pieces; k++) {
        if (AT(*lo, long, k) != next || AT(*hi, long, k) <= next) {
            PyErr_Format(PyExc_ValueError, "%s: piece %zd does not continue at instant %zd", NAMES[first], k, next);
            return 0;
        }
        next = AT(*hi, long, k);
    }
    if (next != n) {
        PyErr_Format(PyExc_ValueError, "%s: the pieces end at instant %zd of %zd", NAMES[first], next, n);
        return 0;
    }
    return 1;
}

/* Position of the axis whose pieces start at view ``first``, at instant i, its piece *k
 * advanced to the one holding i. */
static double position(const Py_buffer *v, int first, Py_ssize_t *k, Py_ssize_t i)
{
    while (AT(v[first + 3], long, *k) <= i)
        (*k)++;
    const double *row = (const double *)((char *)v[first].buf + *k * v[first].strides[0]);
    double p, vel, acc;
    evaluate_held(row, AT(v[TS], double, i) - AT(v[first + 1], double, *k), 1, &p, &vel, &acc);
    return p;
}

static PyObject *inside_stock_py(PyObject *self, PyObject *args)
{
    PyObject *obj[ARRAYS];
    Py_buffer view[ARRAYS];
    double z0, x0, s, s_end, radial, major, slope;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOddddddd:inside_stock", &obj[Z_ROWS], &obj[Z_STARTS], &obj[Z_LO],
                          &obj[Z_HI], &obj[X_ROWS], &obj[X_STARTS], &obj[X_LO], &obj[X_HI], &obj[TS], &z0, &x0,
                          &s, &s_end, &radial, &major, &slope))
        return NULL;
    int taken = take_all(obj, view, ARRAYS, "ddllddlld", ARRAYS, NAMES);
    int ok = taken == ARRAYS && view[TS].ndim == 1;
    if (taken == ARRAYS && !ok)
        PyErr_SetString(PyExc_ValueError, "ts: expected one dimension");
    const Py_ssize_t n = ok ? view[TS].shape[0] : 0;
    ok = ok && covers(view, Z_ROWS, n) && covers(view, X_ROWS, n);
    int inside = 0;
    if (ok) {
        Py_ssize_t kz = 0, kx = 0;
        for (Py_ssize_t i = 0; i < n && !inside; i++) {
            const double d = position(view, Z_ROWS, &kz, i) - z0;  /* program z */
            if (!(s * d >= 0.0 && s * d <= s_end))  /* not over the thread */
                continue;
            const double surface = major + slope * d;
            inside = radial * (position(view, X_ROWS, &kx, i) - x0 - surface) > 0.0;
        }
    }
    PyObject *done = finish(view, taken, ok);
    if (done == NULL)
        return NULL;
    Py_DECREF(done);
    return PyBool_FromLong(inside);
}

static PyMethodDef METHODS[] = {
    {"inside_stock", inside_stock_py, METH_VARARGS,
     "inside_stock(z_rows, z_starts, z_lo, z_hi, x_rows, x_starts, x_lo, x_hi, ts, z0, x0, s, s_end, radial,\n"
     "major, slope): whether at some instant of ts, z (its pieces: rows, plan-time starts, and the\n"
     "instants [lo, hi) each covers, one after the other) lies over the thread (0 <= s*(z - z0) <= s_end)\n"
     "and x (likewise) inside the stock: radial*(x - x0 - (major + slope*(z - z0))) > 0."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_stock_kernel",
                                    "The thread cycle's stock check (ThreadCycle._cuts_stock).", -1, METHODS};

PyMODINIT_FUNC PyInit__stock_kernel(void) { return PyModule_Create(&MODULE); }
