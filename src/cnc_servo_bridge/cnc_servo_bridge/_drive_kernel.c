/* The servo drive model's kernel: DriveModel.step (drive.py) over many servo periods.
 *
 * Compiled by the package's setup.py when it is installed (pip or colcon), so a node
 * loads a few kilobytes of machine code instead of a JIT compiler. It performs the
 * floating-point operations of DriveModel.step in the same order (IEEE double, no
 * fused multiply-add: setup.py builds it with -ffp-contract=off), so its positions equal
 * the step-by-step numpy model's; test_drive.py checks that on random references with
 * the clamps and quantisation active.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

/* One array argument: a C-contiguous float64 buffer (its length is checked by the caller). */
static int take(PyObject *obj, Py_buffer *view, int writable, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0)
        return -1;
    if (view->itemsize != sizeof(double) || view->format == NULL || strcmp(view->format, "d") != 0) {
        PyErr_Format(PyExc_TypeError, "%s: expected a float64 array", name);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* DriveModel.step over every row, in place on the state; out[0..2] = measured position,
 * velocity and following error before each step. */
static void run(Py_ssize_t rows, Py_ssize_t joints, const double *p_ref, const double *v_ref,
                const double *a_ref, double *position, double *velocity, double *measured,
                const double *kp, const double *velocity_ff, const double *accel_gain,
                const double *decay, const double *v_limit, const double *dv_limit,
                const double *resolution, double period, double *out)
{
    const Py_ssize_t plane = rows * joints;
    for (Py_ssize_t i = 0; i < rows; i++) {
        for (Py_ssize_t j = 0; j < joints; j++) {
            const Py_ssize_t k = i * joints + j;
            const double error = p_ref[k] - measured[j];
            out[k] = measured[j];
            out[plane + k] = velocity[j];
            out[2 * plane + k] = error;
            double v_cmd = velocity_ff[j] * v_ref[k] + accel_gain[j] * a_ref[k] + kp[j] * error;
            v_cmd = v_cmd < -v_limit[j] ? -v_limit[j] : v_cmd;
            v_cmd = v_cmd > v_limit[j] ? v_limit[j] : v_cmd;
            double v_new = v_cmd + (velocity[j] - v_cmd) * decay[j];
            double dv = v_new - velocity[j];
            dv = dv < -dv_limit[j] ? -dv_limit[j] : dv;
            dv = dv > dv_limit[j] ? dv_limit[j] : dv;
            v_new = velocity[j] + dv;
            position[j] = position[j] + 0.5 * (velocity[j] + v_new) * period;
            velocity[j] = v_new;
            /* numpy's round: to nearest, ties to even (rint in the default rounding mode) */
            measured[j] = rint(position[j] / resolution[j]) * resolution[j];
        }
    }
}

enum { P_REF, V_REF, A_REF, POSITION, VELOCITY, MEASURED, KP, VELOCITY_FF, ACCEL_GAIN, DECAY,
       V_LIMIT, DV_LIMIT, RESOLUTION, OUT, ARRAYS };

static const char *const NAMES[ARRAYS] = {
    "p_ref", "v_ref", "a_ref", "position", "velocity", "measured", "kp", "velocity_ff",
    "accel_gain", "decay", "v_limit", "dv_limit", "resolution", "out"};

/* Values in an array argument. */
static Py_ssize_t values(const Py_buffer *view)
{
    return view->len / (Py_ssize_t)sizeof(double);
}

/* The sizes agree: joints from the state, rows from p_ref, and every other array follows. */
static int check_sizes(const Py_buffer *view, Py_ssize_t *rows, Py_ssize_t *joints)
{
    *joints = values(&view[POSITION]);
    if (*joints == 0 || values(&view[P_REF]) % *joints != 0) {
        PyErr_Format(PyExc_ValueError, "p_ref: %zd values are not rows of %zd joints",
                     values(&view[P_REF]), *joints);
        return -1;
    }
    *rows = values(&view[P_REF]) / *joints;
    for (int a = 0; a < OUT; a++) {
        Py_ssize_t expected = a <= A_REF ? *rows * *joints : *joints;
        if (values(&view[a]) != expected) {
            PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", NAMES[a], expected, values(&view[a]));
            return -1;
        }
    }
    if (values(&view[OUT]) != 3 * *rows * *joints) {
        PyErr_Format(PyExc_ValueError, "out: expected %zd values, got %zd", 3 * *rows * *joints, values(&view[OUT]));
        return -1;
    }
    return 0;
}

static PyObject *run_py(PyObject *self, PyObject *args)
{
    PyObject *obj[ARRAYS];
    Py_buffer view[ARRAYS];
    double period;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOOOdO:run", &obj[P_REF], &obj[V_REF], &obj[A_REF],
                          &obj[POSITION], &obj[VELOCITY], &obj[MEASURED], &obj[KP],
                          &obj[VELOCITY_FF], &obj[ACCEL_GAIN], &obj[DECAY], &obj[V_LIMIT],
                          &obj[DV_LIMIT], &obj[RESOLUTION], &period, &obj[OUT]))
        return NULL;
    int taken = 0;
    while (taken < ARRAYS) {
        int writable = taken == POSITION || taken == VELOCITY || taken == MEASURED || taken == OUT;
        if (take(obj[taken], &view[taken], writable, NAMES[taken]) < 0)
            break;
        taken++;
    }
    Py_ssize_t rows, joints;
    int ok = taken == ARRAYS && check_sizes(view, &rows, &joints) == 0;
    if (ok) {
        const double *d[ARRAYS];
        for (int a = 0; a < ARRAYS; a++)
            d[a] = (const double *)view[a].buf;
        Py_BEGIN_ALLOW_THREADS
        run(rows, joints, d[P_REF], d[V_REF], d[A_REF], (double *)view[POSITION].buf,
            (double *)view[VELOCITY].buf, (double *)view[MEASURED].buf, d[KP], d[VELOCITY_FF],
            d[ACCEL_GAIN], d[DECAY], d[V_LIMIT], d[DV_LIMIT], d[RESOLUTION], period,
            (double *)view[OUT].buf);
        Py_END_ALLOW_THREADS
    }
    for (int a = 0; a < taken; a++)
        PyBuffer_Release(&view[a]);
    if (!ok)
        return NULL;
    Py_RETURN_NONE;
}

static PyMethodDef METHODS[] = {
    {"run", run_py, METH_VARARGS,
     "run(p_ref, v_ref, a_ref, position, velocity, measured, kp, velocity_ff, accel_gain, decay,\n"
     "    v_limit, dv_limit, resolution, period, out): DriveModel.step over every row of the\n"
     "references (float64, C order, rows x joints), in place on the state arrays; out (3 x rows\n"
     "x joints) receives the measured position, velocity and following error before each step."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_drive_kernel",
                                    "The servo drive model's compiled kernel (see drive.py).", -1, METHODS};

PyMODINIT_FUNC PyInit__drive_kernel(void)
{
    return PyModule_Create(&MODULE);
}
