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

enum { MAX_PIECES = 64 };  /* of one axis over one air path: a handful */

/* One axis's pieces, as stretches.pieces gives them: (row, start, lo, hi) each, the
 * instants [lo, hi) one after the other over all of [0, n). */
typedef struct {
    Py_ssize_t count;
    Py_buffer rows[MAX_PIECES];
    double starts[MAX_PIECES];
    Py_ssize_t hi[MAX_PIECES];
} Pieces;

static void release(Pieces *pieces)
{
    for (Py_ssize_t k = 0; k < pieces->count; k++)
        PyBuffer_Release(&pieces->rows[k]);
    pieces->count = 0;
}

/* The pieces of ``seq`` into ``pieces``; 0 with the error set (naming ``name``) if they are
 * not pieces covering [0, n) in order. */
static int take_pieces(PyObject *seq, Pieces *pieces, Py_ssize_t n, const char *name)
{
    pieces->count = 0;
    PyObject *fast = PySequence_Fast(seq, name);
    if (fast == NULL)
        return 0;
    const Py_ssize_t count = PySequence_Fast_GET_SIZE(fast);
    Py_ssize_t next = 0;
    int ok = count <= MAX_PIECES;
    if (!ok)
        PyErr_Format(PyExc_ValueError, "%s: more than %d pieces", name, MAX_PIECES);
    for (Py_ssize_t k = 0; ok && k < count; k++) {
        PyObject *row;
        Py_ssize_t lo, hi;
        ok = PyArg_ParseTuple(PySequence_Fast_GET_ITEM(fast, k), "Odnn", &row, &pieces->starts[k], &lo, &hi);
        if (ok && take(row, &pieces->rows[k], 0, "d", name) < 0)
            ok = 0;
        else if (ok) {
            pieces->count = k + 1;
            if (pieces->rows[k].ndim != 1 || pieces->rows[k].shape[0] != ROW || pieces->rows[k].strides[0] != sizeof(double)) {
                PyErr_Format(PyExc_ValueError, "%s: piece %zd's row is not %d contiguous values", name, k, ROW);
                ok = 0;
            } else if (lo != next || hi <= lo) {
                PyErr_Format(PyExc_ValueError, "%s: piece %zd does not continue at instant %zd", name, k, next);
                ok = 0;
            }
            pieces->hi[k] = next = hi;
        }
    }
    if (ok && next != n) {
        PyErr_Format(PyExc_ValueError, "%s: the pieces end at instant %zd of %zd", name, next, n);
        ok = 0;
    }
    Py_DECREF(fast);
    if (!ok)
        release(pieces);
    return ok;
}

/* Position at plan time t, instant i, of the axis whose piece *k is advanced to the one
 * holding i. */
static double position(const Pieces *pieces, Py_ssize_t *k, Py_ssize_t i, double t)
{
    while (pieces->hi[*k] <= i)
        (*k)++;
    double p, v, a;
    evaluate_held((const double *)pieces->rows[*k].buf, t - pieces->starts[*k], 1, &p, &v, &a);
    return p;
}

static PyObject *inside_stock_py(PyObject *self, PyObject *args)
{
    PyObject *z_seq, *x_seq, *ts_obj;
    double z0, x0, s, s_end, radial, major, slope;
    Py_buffer ts;
    Pieces z = {.count = 0}, x = {.count = 0};  /* released below, taken or not */
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOddddddd:inside_stock", &z_seq, &x_seq, &ts_obj, &z0, &x0, &s, &s_end, &radial,
                          &major, &slope))
        return NULL;
    if (take(ts_obj, &ts, 0, "d", "ts") < 0)
        return NULL;
    const Py_ssize_t n = ts.ndim == 1 ? ts.shape[0] : -1;
    if (n < 0)
        PyErr_SetString(PyExc_ValueError, "ts: expected one dimension");
    int ok = n >= 0 && take_pieces(z_seq, &z, n, "z_pieces") && take_pieces(x_seq, &x, n, "x_pieces");
    int inside = 0;
    if (ok) {
        Py_ssize_t kz = 0, kx = 0;
        for (Py_ssize_t i = 0; i < n && !inside; i++) {
            const double t = AT(ts, double, i);
            const double d = position(&z, &kz, i, t) - z0;  /* program z */
            if (!(s * d >= 0.0 && s * d <= s_end))  /* not over the thread */
                continue;
            const double surface = major + slope * d;
            inside = radial * (position(&x, &kx, i, t) - x0 - surface) > 0.0;
        }
    }
    release(&z);
    release(&x);
    PyBuffer_Release(&ts);
    return ok ? PyBool_FromLong(inside) : NULL;
}

static PyMethodDef METHODS[] = {
    {"inside_stock", inside_stock_py, METH_VARARGS,
     "inside_stock(z_pieces, x_pieces, ts, z0, x0, s, s_end, radial, major, slope): whether at some\n"
     "instant of ts, z (its pieces: (row, plan-time start, lo, hi), the instants [lo, hi) one after\n"
     "the other) lies over the thread (0 <= s*(z - z0) <= s_end) and x (likewise) inside the stock:\n"
     "radial*(x - x0 - (major + slope*(z - z0))) > 0."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_stock_kernel",
                                    "The thread cycle's stock check (ThreadCycle._cuts_stock).", -1, METHODS};

PyMODINIT_FUNC PyInit__stock_kernel(void) { return PyModule_Create(&MODULE); }
