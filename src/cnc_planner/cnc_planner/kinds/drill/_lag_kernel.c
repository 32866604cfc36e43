/* The drive model's verdict on a drilling cycle, hole after hole: servo_lag.lag_margins.
 *
 * For each hole the feedback is scanned from where the hole's S1 starts (or the previous
 * hole's tip came back above its plane) to the next hole's S1: when the tip goes below
 * the plane of the move into the hole and comes back above the plane of the move out of
 * it, where its bottom is, and which samples have X/Y off the hole. In numpy this took a
 * dozen calls per hole, a sixth of a long plate's planning; here it is one pass over the
 * samples. The comparisons are those of servo_lag.py, and the distance is libm's hypot,
 * as np.hypot computes it, so the margins are the same (plans hashed before and after
 * are equal; test_drilling.py checks the kernel against the numpy scan).
 */
#include <math.h>

#include "../../kernel_buffers.h"

#define FB(view, k, c) AT2(view, double, k, c)

enum { FEEDBACK, STARTS, INTO, OUT, HOLE_X, HOLE_Y, DOWN, UP, ARRAYS };
static const char *const NAMES[ARRAYS] = {"feedback", "starts", "into", "out", "hole_x", "hole_y", "down", "up"};
static const char FORMATS[ARRAYS + 1] = "dldddddd";

/* Hole after hole, as servo_lag.lag_margins scans them (its comments say why). */
static void scan(const Py_buffer *v, Py_ssize_t holes, double tol)
{
    Py_ssize_t ku = 0;
    for (Py_ssize_t i = 0; i < holes; i++) {
        Py_ssize_t lo = AT(v[STARTS], long, i), hi = AT(v[STARTS], long, i + 2);
        lo = lo > ku ? lo : ku;
        const double into = AT(v[INTO], double, i), out = AT(v[OUT], double, i);
        const double both = into < out ? into : out;
        AT(v[DOWN], double, i) = 0.0;
        AT(v[UP], double, i) = 0.0;
        Py_ssize_t kv = lo;
        while (kv < hi && !(FB(v[FEEDBACK], kv, 2) < both))
            kv++;
        if (kv >= hi)
            continue;  /* no visit below both planes */
        Py_ssize_t kw = kv;
        while (kw < hi && FB(v[FEEDBACK], kw, 2) < both)
            kw++;
        Py_ssize_t kb = kv;  /* the hole's bottom: the first lowest sample of the visit */
        for (Py_ssize_t k = kv; k < kw; k++)
            if (FB(v[FEEDBACK], k, 2) < FB(v[FEEDBACK], kb, 2))
                kb = k;
        Py_ssize_t kd = lo;
        while (kd < hi && !(FB(v[FEEDBACK], kd, 2) < into))
            kd++;
        ku = kb;
        while (ku < hi && FB(v[FEEDBACK], ku, 2) < out)
            ku++;
        const double x = AT(v[HOLE_X], double, i), y = AT(v[HOLE_Y], double, i);
        Py_ssize_t late = lo;  /* one past the last off-hole sample before the bottom */
        for (Py_ssize_t k = kb - 1; k >= lo; k--)
            if (hypot(FB(v[FEEDBACK], k, 0) - x, FB(v[FEEDBACK], k, 1) - y) > tol) {
                late = k + 1;
                break;
            }
        Py_ssize_t early = hi;  /* the first off-hole sample from the bottom on */
        for (Py_ssize_t k = kb; k < hi; k++)
            if (hypot(FB(v[FEEDBACK], k, 0) - x, FB(v[FEEDBACK], k, 1) - y) > tol) {
                early = k;
                break;
            }
        AT(v[DOWN], double, i) = (double)(late - kd);
        AT(v[UP], double, i) = (double)(ku - early);
    }
}

static PyObject *margins_py(PyObject *self, PyObject *args)
{
    PyObject *obj[ARRAYS];
    Py_buffer view[ARRAYS];
    double tol;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOdOO:margins", &obj[FEEDBACK], &obj[STARTS], &obj[INTO], &obj[OUT],
                          &obj[HOLE_X], &obj[HOLE_Y], &tol, &obj[DOWN], &obj[UP]))
        return NULL;
    int taken = take_all(obj, view, ARRAYS, FORMATS, DOWN, NAMES);
    int ok = taken == ARRAYS;
    Py_ssize_t holes = 0;
    if (ok) {
        holes = view[INTO].shape[0];
        Py_ssize_t samples = view[FEEDBACK].shape[0];
        if (view[FEEDBACK].ndim != 2 || view[FEEDBACK].shape[1] != 3) {
            PyErr_SetString(PyExc_ValueError, "feedback: expected (samples, 3): x, y, z");
            ok = 0;
        }
        for (int k = STARTS; ok && k < ARRAYS; k++) {
            Py_ssize_t expected = k == STARTS ? holes + 2 : holes;
            if (view[k].ndim != 1 || view[k].shape[0] != expected) {
                PyErr_Format(PyExc_ValueError, "%s: expected %zd values", NAMES[k], expected);
                ok = 0;
            }
        }
        for (Py_ssize_t i = 0; ok && i < holes + 2; i++) {
            Py_ssize_t s = AT(view[STARTS], long, i);
            if (s < 0 || s > samples || (i > 0 && s < AT(view[STARTS], long, i - 1))) {
                PyErr_Format(PyExc_ValueError, "starts[%zd]: %zd is not a sorted index into %zd samples", i, s,
                             samples);
                ok = 0;
            }
        }
    }
    if (ok) {
        Py_BEGIN_ALLOW_THREADS
        scan(view, holes, tol);
        Py_END_ALLOW_THREADS
    }
    return finish(view, taken, ok);
}

static PyMethodDef METHODS[] = {
    {"margins", margins_py, METH_VARARGS,
     "margins(feedback, starts, into, out, hole_x, hole_y, tol, down, up): servo_lag.lag_margins'\n"
     "scan of the (samples, 3) X/Y/Z feedback, hole after hole, into down and up (servo periods)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_lag_kernel",
                                    "The drive model's lag margins of a drilling cycle (servo_lag.py).", -1, METHODS};

PyMODINIT_FUNC PyInit__lag_kernel(void)
{
    return PyModule_Create(&MODULE);
}
