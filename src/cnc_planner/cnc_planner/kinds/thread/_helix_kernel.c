/* The helix of one pass, its vibration included (helix.py), outside its sines and cosines.
 *
 * The thread cycle evaluates the helix about twenty times per plan, most of them at a few
 * hundred points or at one; in numpy each evaluation cost some thirty calls, about 25 us
 * before any arithmetic. Here the arithmetic runs in two loops around numpy's sine and
 * cosine (numpy keeps those, so that they are the very values waveform() gives): `phase`
 * gives the waveform's angle, `state` the positions, velocities and accelerations. Every
 * operation is helix()'s and waveform()'s numpy one on float64, in the same order
 * (setup.py: -ffp-contract=off), so the helix is the same to the last bit
 * (test_thread_helix.py compares the two).
 */
#include <math.h>

#include "../../kernel_buffers.h"

/* numpy's float remainder (np.mod, npy_divmod) by 1: fmod, moved into [0, 1) when negative,
 * +0 when exact. */
static inline double remainder_one(double u)
{
    double mod = fmod(u, 1.0);
    if (mod) {
        if (mod < 0.0)
            mod += 1.0;
    } else {
        mod = copysign(0.0, 1.0);
    }
    return mod;
}

/* The arguments' buffers (take_all: float64, the last `writable` of them written), each one
 * dimension of n values (n: the first's). Whether all are right; *taken: how many to release. */
static int take_vectors(PyObject **obj, Py_buffer *view, int count, int writable, const char *const *names,
                        Py_ssize_t *n, int *taken)
{
    *taken = take_all(obj, view, count, "dddd", count - writable, names);  /* count <= 4 */
    if (*taken < count)
        return 0;
    *n = view[0].shape[0];
    for (int k = 0; k < count; k++) {
        if (view[k].ndim != 1) {
            PyErr_Format(PyExc_ValueError, "%s: expected one dimension", names[k]);
            return 0;
        }
        if (view[k].shape[0] != *n) {
            PyErr_Format(PyExc_ValueError, "%s: expected %zd values", names[k], *n);
            return 0;
        }
    }
    return 1;
}

static PyObject *phase_py(PyObject *self, PyObject *args)
{
    static const char *const names[] = {"psi", "angle"};
    PyObject *obj[2];
    Py_buffer view[2];
    double per_rev, phase, two_pi;
    Py_ssize_t n = 0;
    int taken;
    (void)self;
    if (!PyArg_ParseTuple(args, "OdddO:phase", &obj[0], &per_rev, &phase, &two_pi, &obj[1]))
        return NULL;
    const int ok = take_vectors(obj, view, 2, 1, names, &n, &taken);
    if (ok) {
        for (Py_ssize_t i = 0; i < n; i++) {
            const double u = per_rev * AT(view[0], double, i) / two_pi + phase;
            AT(view[1], double, i) = two_pi * remainder_one(u);
        }
    }
    return finish(view, taken, ok);
}

/* The scalars of `state`, in its argument order: helix()'s products of the spec and the
 * pass, computed once in Python. */
typedef struct {
    double pi, two_pi, two_pi_squared, depth, amplitude, amplitude_rate, amplitude_rate_squared, start_z,
        s_pitch, origin_x, major, slope, radial, origin_z, s, tan, cone, lead_speed, s_tan;
} Helix;

static PyObject *state_py(PyObject *self, PyObject *args)
{
    static const char *const names[] = {"psi", "sin", "cos", "out"};
    PyObject *obj[4];
    Py_buffer view[4];
    Helix h;
    Py_ssize_t n = 0;
    int taken;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOO(ddddddddddddddddddd):state", &obj[0], &obj[1], &obj[2], &obj[3], &h.pi,
                          &h.two_pi, &h.two_pi_squared, &h.depth, &h.amplitude, &h.amplitude_rate,
                          &h.amplitude_rate_squared, &h.start_z, &h.s_pitch, &h.origin_x, &h.major, &h.slope,
                          &h.radial, &h.origin_z, &h.s, &h.tan, &h.cone, &h.lead_speed, &h.s_tan))
        return NULL;
    int ok = take_vectors(obj, view, 3, 0, names, &n, &taken);
    Py_buffer *out = &view[3];
    if (ok && PyObject_GetBuffer(obj[3], out, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) == 0) {
        if (out->format == NULL || strcmp(out->format, "d") != 0 || out->len != (Py_ssize_t)(6 * n * sizeof(double))) {
            PyErr_Format(PyExc_ValueError, "out: expected a C-contiguous float64 (3, %zd, 2) array", n);
            PyBuffer_Release(out);
            ok = 0;
        }
    } else {
        ok = 0;
    }
    if (ok) {
        double *o = out->buf;  /* (3, n, 2): position, velocity, acceleration of x and z */
        for (Py_ssize_t i = 0; i < n; i++) {
            const double psi = AT(view[0], double, i), sin_ = AT(view[1], double, i), cos_ = AT(view[2], double, i);
            const double w = (1.0 - cos_) / 2.0, w1 = h.pi * sin_, w2 = h.two_pi_squared * cos_;  /* waveform() */
            const double depth = h.depth - h.amplitude * (1.0 - w);
            const double ddepth = h.amplitude_rate * w1, dddepth = h.amplitude_rate_squared * w2;
            const double groove = h.start_z + h.s_pitch * psi / h.two_pi;
            o[2 * i] = h.origin_x + (h.major + h.slope * groove) + h.radial * depth;
            o[2 * i + 1] = h.origin_z + groove + h.s * depth * h.tan;
            o[2 * (n + i)] = h.cone + h.radial * ddepth;
            o[2 * (n + i) + 1] = h.s * (h.lead_speed + h.tan * ddepth);
            o[2 * (2 * n + i)] = h.radial * dddepth;
            o[2 * (2 * n + i) + 1] = h.s_tan * dddepth;
        }
        PyBuffer_Release(out);
    }
    return finish(view, taken, ok);
}

static PyMethodDef METHODS[] = {
    {"phase", phase_py, METH_VARARGS,
     "phase(psi, per_rev, phase, two_pi, angle): angle = two_pi * np.mod(per_rev * psi / two_pi + phase, 1),\n"
     "the waveform's angle at helix angles psi (float64, one dimension, any strides)."},
    {"state", state_py, METH_VARARGS,
     "state(psi, sin, cos, out, scalars): helix() into out (C-contiguous (3, len(psi), 2)) from psi and\n"
     "the sine and cosine of phase()'s angle; scalars: the Helix struct's fields in order."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_helix_kernel",
                                    "The thread pass's helix outside its sines and cosines (helix.py).", -1, METHODS};

PyMODINIT_FUNC PyInit__helix_kernel(void) { return PyModule_Create(&MODULE); }
