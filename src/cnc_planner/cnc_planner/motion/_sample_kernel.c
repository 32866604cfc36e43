/* Sampling many pieces of ruckig trajectories at once: jerk_profile.sample_spans.
 *
 * A timeline of a long job holds tens of thousands of short ruckig pieces, and a plan is
 * sampled at every servo period several times while it is made (the timing search, the
 * bridge-contract check, the stream). In numpy each pass over them builds a dozen
 * temporaries per instant; here each instant is evaluated where it is written.
 *
 * Each piece is one degree of freedom of a ruckig trajectory, given as a row of
 * TrajectorySampler.rows (layout in jerk_profile.py). The evaluation is
 * TrajectorySampler._sample_dof's (ruckig's at_time: brake phases, seven phases of
 * constant jerk, constant acceleration past the end) with the same floating-point
 * operations in the same order, no fused multiply-add (setup.py: -ffp-contract=off), so
 * the values equal numpy's; test_jerk_profile.py checks that.
 */
#include "../kernel_buffers.h"
#include "../ruckig_piece.h"

enum { TABLE, STARTS, LO, HI, TS, P, V, A, ARRAYS };
static const char *const NAMES[ARRAYS] = {"rows", "starts", "lo", "hi", "ts", "p", "v", "a"};

static PyObject *spans_py(PyObject *self, PyObject *args)
{
    PyObject *obj[ARRAYS];
    Py_buffer view[ARRAYS];
    int held = 0;  /* each piece holds its end state past its end, instead of its final acceleration */
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOO|p:spans", &obj[TABLE], &obj[STARTS], &obj[LO], &obj[HI], &obj[TS],
                          &obj[P], &obj[V], &obj[A], &held))
        return NULL;
    int taken = take_all(obj, view, ARRAYS, "ddlldddd", P, NAMES);
    int ok = taken == ARRAYS;
    Py_ssize_t pieces = 0, n = 0;
    if (ok) {
        pieces = view[STARTS].shape[0];
        n = view[TS].shape[0];
        if (view[TABLE].ndim != 2 || view[TABLE].shape[0] != pieces || view[TABLE].shape[1] != ROW
            || view[TABLE].strides[1] != sizeof(double)) {
            PyErr_Format(PyExc_ValueError, "rows: expected (%zd, %d) float64 rows", pieces, ROW);
            ok = 0;
        }
        for (int k = LO; ok && k < ARRAYS; k++) {
            Py_ssize_t expected = k == LO || k == HI ? pieces : n;
            if (view[k].ndim != 1 || view[k].shape[0] != expected) {
                PyErr_Format(PyExc_ValueError, "%s: expected %zd values", NAMES[k], expected);
                ok = 0;
            }
        }
        for (Py_ssize_t k = 0; ok && k < pieces; k++) {
            Py_ssize_t lo = AT(view[LO], long, k), hi = AT(view[HI], long, k);
            if (lo < 0 || hi > n || lo > hi) {
                PyErr_Format(PyExc_ValueError, "piece %zd: instants [%zd, %zd) outside [0, %zd)", k, lo, hi, n);
                ok = 0;
            }
        }
    }
    if (ok) {
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t k = 0; k < pieces; k++) {
            const double *row = (const double *)((char *)view[TABLE].buf + k * view[TABLE].strides[0]);
            const double start = AT(view[STARTS], double, k);
            for (Py_ssize_t i = AT(view[LO], long, k); i < AT(view[HI], long, k); i++)
                evaluate_held(row, AT(view[TS], double, i) - start, held, &AT(view[P], double, i),
                              &AT(view[V], double, i), &AT(view[A], double, i));
        }
        Py_END_ALLOW_THREADS
    }
    return finish(view, taken, ok);
}

/* np.interp(x, j * period for j < k, fp) at one x, as numpy computes it (its left and right
 * values are fp's ends; the interval found by index instead of numpy's binary search is
 * the same one, the grid being strictly increasing). */
static double interp(double x, Py_ssize_t k, double period, const double *fp)
{
    if (k == 1 || x < 0.0)
        return fp[0];
    const double last = (double)(k - 1) * period;
    if (x > last)
        return fp[k - 1];
    Py_ssize_t j = (Py_ssize_t)(x / period);
    j = j > k - 1 ? k - 1 : j;
    while (j > 0 && (double)j * period > x)
        j--;
    while (j < k - 1 && (double)(j + 1) * period <= x)
        j++;
    const double xj = (double)j * period;
    if (j == k - 1 || xj == x)
        return fp[j];
    const double xk = (double)(j + 1) * period;
    const double slope = (fp[j + 1] - fp[j]) / (xk - xj);
    double value = slope * (x - xj) + fp[j];
    if (value != value) {  /* numpy's fallback for a non-finite slope */
        value = slope * (x - xk) + fp[j + 1];
        if (value != value && fp[j] == fp[j + 1])
            value = fp[j];
    }
    return value;
}

enum { C_TABLE, C_OFFSET, C_LENGTH, C_START, C_LO, C_HI, C_TS, C_P, C_V, C_A, C_ARRAYS };
static const char *const C_NAMES[C_ARRAYS] = {"table", "offset", "length", "starts", "lo", "hi", "ts", "p", "v", "a"};

static PyObject *corrections_py(PyObject *self, PyObject *args)
{
    PyObject *obj[C_ARRAYS];
    Py_buffer view[C_ARRAYS];
    double period;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOdOOOO:corrections", &obj[C_TABLE], &obj[C_OFFSET], &obj[C_LENGTH],
                          &obj[C_START], &obj[C_LO], &obj[C_HI], &period, &obj[C_TS], &obj[C_P], &obj[C_V],
                          &obj[C_A]))
        return NULL;
    int taken = take_all(obj, view, C_ARRAYS, "dlldlldddd", C_P, C_NAMES);
    int ok = taken == C_ARRAYS;
    Py_ssize_t parts = 0, n = 0, size = 0;
    if (ok) {
        parts = view[C_START].shape[0];
        n = view[C_TS].shape[0];
        size = view[C_TABLE].shape[0];
        for (int k = 0; ok && k < C_ARRAYS; k++) {
            Py_ssize_t expected = k == C_TABLE ? size : k < C_TS ? parts : n;
            if (view[k].ndim != 1 || view[k].shape[0] != expected) {
                PyErr_Format(PyExc_ValueError, "%s: expected %zd values", C_NAMES[k], expected);
                ok = 0;
            }
        }
        if (ok && view[C_TABLE].strides[0] != sizeof(double)) {
            PyErr_SetString(PyExc_ValueError, "table: expected a contiguous array");
            ok = 0;
        }
        if (ok && !(period > 0.0)) {
            PyErr_SetString(PyExc_ValueError, "period: must be positive");
            ok = 0;
        }
        for (Py_ssize_t k = 0; ok && k < parts; k++) {
            Py_ssize_t lo = AT(view[C_LO], long, k), hi = AT(view[C_HI], long, k);
            Py_ssize_t offset = AT(view[C_OFFSET], long, k), length = AT(view[C_LENGTH], long, k);
            if (lo < 0 || hi > n || lo > hi || length < 1 || offset < 0 || offset + 3 * length > size) {
                PyErr_Format(PyExc_ValueError, "part %zd: instants [%zd, %zd) of %zd, or its %zd samples at %zd "
                             "outside the table of %zd", k, lo, hi, n, length, offset, size);
                ok = 0;
            }
        }
    }
    if (ok) {
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t k = 0; k < parts; k++) {
            const Py_ssize_t length = AT(view[C_LENGTH], long, k);
            const double *fp = &AT(view[C_TABLE], double, AT(view[C_OFFSET], long, k));
            const double start = AT(view[C_START], double, k);
            for (Py_ssize_t i = AT(view[C_LO], long, k); i < AT(view[C_HI], long, k); i++) {
                const double x = AT(view[C_TS], double, i) - start;
                AT(view[C_P], double, i) += interp(x, length, period, fp);
                AT(view[C_V], double, i) += interp(x, length, period, fp + length);
                AT(view[C_A], double, i) += interp(x, length, period, fp + 2 * length);
            }
        }
        Py_END_ALLOW_THREADS
    }
    return finish(view, taken, ok);
}

static PyMethodDef METHODS[] = {
    {"spans", spans_py, METH_VARARGS,
     "spans(rows, starts, lo, hi, ts, p, v, a, held=False): piece k (rows[k], from plan time starts[k]) at\n"
     "the instants ts[lo[k]:hi[k]], written to p, v and a at the same indices; held: each piece's end\n"
     "state past its end."},
    {"corrections", corrections_py, METH_VARARGS,
     "corrections(table, offset, length, starts, lo, hi, period, ts, p, v, a): part k, in order, adds\n"
     "np.interp(ts[i] - starts[k], servo grid of length[k] samples, its p, v or a samples, which lie\n"
     "one after the other from table[offset[k]]) to p, v and a at each i in [lo[k], hi[k])."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_sample_kernel",
                                    "Sampling ruckig pieces in bulk (jerk_profile.sample_spans).", -1, METHODS};

PyMODINIT_FUNC PyInit__sample_kernel(void)
{
    return PyModule_Create(&MODULE);
}
