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
#include <float.h>
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

/* A velocity below the smallest normal double is zero (its sign kept), as DriveModel.step
 * has it: a velocity decaying at rest otherwise sticks at the smallest subnormal (0.61 of
 * it rounds back up to it) and every later step of that joint computes on subnormals,
 * which this FPU does 5-20 times slower: most of a drilling plan's drive-model time. */
static inline double settled(double velocity)
{
    return fabs(velocity) < DBL_MIN ? 0.0 * velocity : velocity;
}

/* One joint's drive parameters. */
typedef struct {
    double kp, velocity_ff, accel_gain, decay, v_limit, dv_limit, resolution;
} Drive;

/* DriveModel.step for one joint and one period: the state (position, velocity, measured) in
 * place; returns the following error. */
static inline double step(const Drive *d, double period, double p_ref, double v_ref, double a_ref,
                          double *position, double *velocity, double *measured)
{
    const double error = p_ref - *measured;
    double v_cmd = d->velocity_ff * v_ref + d->accel_gain * a_ref + d->kp * error;
    v_cmd = v_cmd < -d->v_limit ? -d->v_limit : v_cmd;
    v_cmd = v_cmd > d->v_limit ? d->v_limit : v_cmd;
    double v_new = v_cmd + (*velocity - v_cmd) * d->decay;
    double dv = v_new - *velocity;
    dv = dv < -d->dv_limit ? -d->dv_limit : dv;
    dv = dv > d->dv_limit ? d->dv_limit : dv;
    v_new = settled(*velocity + dv);
    *position = *position + 0.5 * (*velocity + v_new) * period;
    *velocity = v_new;
    /* numpy's round: to nearest, ties to even (rint in the default rounding mode) */
    *measured = rint(*position / d->resolution) * d->resolution;
    return error;
}

enum { MAX_IN_REGISTERS = 6 };  /* joints whose state the loop below keeps in registers */

/* DriveModel.step over every row for `joints` joints, a constant once inlined, of rows
 * `stride` values apart (the joints being a group of a wider row): the loop over the joints
 * unrolls, their state stays in registers, and each joint's chain of dependent operations
 * runs beside the others'. */
static inline __attribute__((always_inline)) void run_fixed(
    const Py_ssize_t joints, Py_ssize_t rows, Py_ssize_t stride, Py_ssize_t plane, const double *restrict p_ref,
    const double *restrict v_ref, const double *restrict a_ref, double *restrict position, double *restrict velocity,
    double *restrict measured, const Drive *drives, double period, double *restrict out)
{
    const Py_ssize_t end = rows * stride;
    double pos[MAX_IN_REGISTERS], vel[MAX_IN_REGISTERS], meas[MAX_IN_REGISTERS];
#pragma GCC unroll 8
    for (Py_ssize_t j = 0; j < joints; j++)
        pos[j] = position[j], vel[j] = velocity[j], meas[j] = measured[j];
    for (Py_ssize_t k = 0; k < end; k += stride) {
#pragma GCC unroll 8
        for (Py_ssize_t j = 0; j < joints; j++) {
            out[k + j] = meas[j];
            out[plane + k + j] = vel[j];
            out[2 * plane + k + j] = step(&drives[j], period, p_ref[k + j], v_ref[k + j], a_ref[k + j], &pos[j],
                                          &vel[j], &meas[j]);
        }
    }
#pragma GCC unroll 8
    for (Py_ssize_t j = 0; j < joints; j++)
        position[j] = pos[j], velocity[j] = vel[j], measured[j] = meas[j];
}

enum { TILE_ROWS = 256 };  /* rows run by every group before the next rows: they stay in the cache */

/* DriveModel.step over every row, in place on the state; out[0..2] = measured position,
 * velocity and following error before each step. The joints go in groups of up to
 * MAX_IN_REGISTERS (every machine here is one group) with their state in registers, over
 * TILE_ROWS rows at a time: the planner's tolerance corners are dozens of columns and tens
 * of thousands of rows, which a group at a time over every row read from memory once per
 * group. The joints do not interact, so the order the groups and tiles run in changes no
 * value. */
static void run(Py_ssize_t rows, Py_ssize_t joints, const double *restrict p_ref, const double *restrict v_ref,
                const double *restrict a_ref, double *restrict position, double *restrict velocity,
                double *restrict measured, const Drive *drives, double period, double *restrict out)
{
    const Py_ssize_t plane = rows * joints;
    for (Py_ssize_t r = 0; r < rows; r += TILE_ROWS) {
        const Py_ssize_t tile = rows - r < TILE_ROWS ? rows - r : TILE_ROWS, at = r * joints;
        for (Py_ssize_t g = 0; g < joints; g += MAX_IN_REGISTERS) {
            const Py_ssize_t n = joints - g < MAX_IN_REGISTERS ? joints - g : MAX_IN_REGISTERS;
            const double *p = p_ref + at + g, *v = v_ref + at + g, *a = a_ref + at + g;
            double *pos = position + g, *vel = velocity + g, *meas = measured + g, *o = out + at + g;
            const Drive *d = drives + g;
            switch (n) {
            case 1: run_fixed(1, tile, joints, plane, p, v, a, pos, vel, meas, d, period, o); break;
            case 2: run_fixed(2, tile, joints, plane, p, v, a, pos, vel, meas, d, period, o); break;
            case 3: run_fixed(3, tile, joints, plane, p, v, a, pos, vel, meas, d, period, o); break;
            case 4: run_fixed(4, tile, joints, plane, p, v, a, pos, vel, meas, d, period, o); break;
            case 5: run_fixed(5, tile, joints, plane, p, v, a, pos, vel, meas, d, period, o); break;
            default: run_fixed(6, tile, joints, plane, p, v, a, pos, vel, meas, d, period, o); break;
            }
        }
    }
}

/* run_fixed for columns that read shared references: column j's reference rows are
 * `width` values apart from p[j] (its source joint's column, its delay earlier); pc[j] is
 * the same column as commanded (no delay), against which the following error is taken. */
static inline __attribute__((always_inline)) void run_shared_fixed(
    const Py_ssize_t joints, Py_ssize_t rows, Py_ssize_t stride, Py_ssize_t plane, Py_ssize_t width,
    const double *const *p, const double *const *v, const double *const *a, const double *const *pc,
    double *restrict position, double *restrict velocity, double *restrict measured, const Drive *drives,
    double period, double *restrict out)
{
    double pos[MAX_IN_REGISTERS], vel[MAX_IN_REGISTERS], meas[MAX_IN_REGISTERS];
#pragma GCC unroll 8
    for (Py_ssize_t j = 0; j < joints; j++)
        pos[j] = position[j], vel[j] = velocity[j], meas[j] = measured[j];
    for (Py_ssize_t r = 0; r < rows; r++) {
        const Py_ssize_t k = r * stride, at = r * width;
#pragma GCC unroll 8
        for (Py_ssize_t j = 0; j < joints; j++) {
            const double before = meas[j];
            out[k + j] = before;
            out[plane + k + j] = vel[j];
            step(&drives[j], period, p[j][at], v[j][at], a[j][at], &pos[j], &vel[j], &meas[j]);
            out[2 * plane + k + j] = pc[j][at] - before;
        }
    }
#pragma GCC unroll 8
    for (Py_ssize_t j = 0; j < joints; j++)
        position[j] = pos[j], velocity[j] = vel[j], measured[j] = meas[j];
}

/* run, the references given once per source joint (`width` of them per row, after `depth`
 * rows still in transit from before): column j reads source[j]'s, delay[j] rows earlier. */
static void run_shared(Py_ssize_t rows, Py_ssize_t joints, Py_ssize_t width, Py_ssize_t depth,
                       const double *p_src, const double *v_src, const double *a_src, const Py_ssize_t *source,
                       const Py_ssize_t *delay, double *restrict position, double *restrict velocity,
                       double *restrict measured, const Drive *drives, double period, double *restrict out)
{
    const Py_ssize_t plane = rows * joints;
    for (Py_ssize_t r = 0; r < rows; r += TILE_ROWS) {
        const Py_ssize_t tile = rows - r < TILE_ROWS ? rows - r : TILE_ROWS;
        for (Py_ssize_t g = 0; g < joints; g += MAX_IN_REGISTERS) {
            const Py_ssize_t n = joints - g < MAX_IN_REGISTERS ? joints - g : MAX_IN_REGISTERS;
            const double *p[MAX_IN_REGISTERS], *v[MAX_IN_REGISTERS], *a[MAX_IN_REGISTERS], *pc[MAX_IN_REGISTERS];
            for (Py_ssize_t j = 0; j < n; j++) {
                const Py_ssize_t at = (r + depth - delay[g + j]) * width + source[g + j];
                p[j] = p_src + at, v[j] = v_src + at, a[j] = a_src + at;
                pc[j] = p_src + (r + depth) * width + source[g + j];
            }
            double *pos = position + g, *vel = velocity + g, *meas = measured + g, *o = out + r * joints + g;
            const Drive *d = drives + g;
            switch (n) {
            case 1: run_shared_fixed(1, tile, joints, plane, width, p, v, a, pc, pos, vel, meas, d, period, o); break;
            case 2: run_shared_fixed(2, tile, joints, plane, width, p, v, a, pc, pos, vel, meas, d, period, o); break;
            case 3: run_shared_fixed(3, tile, joints, plane, width, p, v, a, pc, pos, vel, meas, d, period, o); break;
            case 4: run_shared_fixed(4, tile, joints, plane, width, p, v, a, pc, pos, vel, meas, d, period, o); break;
            case 5: run_shared_fixed(5, tile, joints, plane, width, p, v, a, pc, pos, vel, meas, d, period, o); break;
            default: run_shared_fixed(6, tile, joints, plane, width, p, v, a, pc, pos, vel, meas, d, period, o); break;
            }
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

/* The sizes agree: the first `row_arrays` arrays hold rows x joints values, the others up to
 * `out` one per joint (joints from the first of them), and out 3 x rows x joints. */
static int check_sizes(const Py_buffer *view, const char *const *names, int row_arrays, int out, Py_ssize_t *rows,
                       Py_ssize_t *joints)
{
    *joints = values(&view[row_arrays]);
    if (*joints == 0 || values(&view[0]) % *joints != 0) {
        PyErr_Format(PyExc_ValueError, "%s: %zd values are not rows of %zd joints", names[0], values(&view[0]),
                     *joints);
        return -1;
    }
    *rows = values(&view[0]) / *joints;
    for (int a = 0; a < out; a++) {
        Py_ssize_t expected = a < row_arrays ? *rows * *joints : *joints;
        if (values(&view[a]) != expected) {
            PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", names[a], expected, values(&view[a]));
            return -1;
        }
    }
    if (values(&view[out]) != 3 * *rows * *joints) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values, got %zd", names[out], 3 * *rows * *joints,
                     values(&view[out]));
        return -1;
    }
    return 0;
}

/* Every array argument in turn (writable where its bit is set in `writable`); how many were
 * taken: fewer than `count` with a Python error set. */
static int take_all(PyObject *const *obj, Py_buffer *view, int count, unsigned long writable, const char *const *names)
{
    int taken = 0;
    while (taken < count && take(obj[taken], &view[taken], (int)((writable >> taken) & 1UL), names[taken]) == 0)
        taken++;
    return taken;
}

/* The arrays' buffers into d, and the drives' parameters from them (PyMem: the caller
 * frees it); NULL with MemoryError set. */
static Drive *drives_of(const Py_buffer *view, const double **d, Py_ssize_t joints)
{
    for (int a = 0; a < ARRAYS; a++)
        d[a] = (const double *)view[a].buf;
    Drive *drives = PyMem_Malloc((size_t)joints * sizeof(Drive));
    if (drives == NULL) {
        PyErr_NoMemory();
        return NULL;
    }
    for (Py_ssize_t j = 0; j < joints; j++)
        drives[j] = (Drive){d[KP][j], d[VELOCITY_FF][j], d[ACCEL_GAIN][j], d[DECAY][j], d[V_LIMIT][j],
                            d[DV_LIMIT][j], d[RESOLUTION][j]};
    return drives;
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
    int taken = take_all(obj, view, ARRAYS, 1UL << POSITION | 1UL << VELOCITY | 1UL << MEASURED | 1UL << OUT, NAMES);
    Py_ssize_t rows, joints;
    int ok = taken == ARRAYS && check_sizes(view, NAMES, POSITION, OUT, &rows, &joints) == 0;
    if (ok) {
        const double *d[ARRAYS];
        Drive *drives = drives_of(view, d, joints);
        ok = drives != NULL;
        if (ok) {
            Py_BEGIN_ALLOW_THREADS
            run(rows, joints, d[P_REF], d[V_REF], d[A_REF], (double *)view[POSITION].buf,
                (double *)view[VELOCITY].buf, (double *)view[MEASURED].buf, drives, period,
                (double *)view[OUT].buf);
            Py_END_ALLOW_THREADS
        }
        PyMem_Free(drives);
    }
    for (int a = 0; a < taken; a++)
        PyBuffer_Release(&view[a]);
    if (!ok)
        return NULL;
    Py_RETURN_NONE;
}

/* One joint's plant-only losses: Coulomb friction in the velocity loop (the velocity command
 * it takes to break the axis away, m/s or rad/s) and backlash between motor and load (m or rad). */
typedef struct {
    double friction, backlash;
} Losses;

/* DriveModel.step with the losses for one joint and one period: the motor (position,
 * velocity), the load after the backlash and the encoder reading of the load plus `noise`. */
static inline double step_plant(const Drive *d, const Losses *l, double period, double p_ref, double v_ref,
                                double a_ref, double noise, double *position, double *velocity, double *load,
                                double *measured)
{
    const double error = p_ref - *measured;
    double v_cmd = d->velocity_ff * v_ref + d->accel_gain * a_ref + d->kp * error;
    v_cmd = v_cmd < -d->v_limit ? -d->v_limit : v_cmd;
    v_cmd = v_cmd > d->v_limit ? d->v_limit : v_cmd;
    double v_new;
    if (l->friction > 0.0) {
        /* friction opposes the motion (or, at rest, the command) and never reverses it */
        const double dir = *velocity != 0.0 ? copysign(1.0, *velocity) : (v_cmd != 0.0 ? copysign(1.0, v_cmd) : 0.0);
        const double v_eff = v_cmd - l->friction * dir;
        v_new = v_eff + (*velocity - v_eff) * d->decay;
        if (v_new * dir <= 0.0)
            v_new = 0.0;
    } else {
        v_new = v_cmd + (*velocity - v_cmd) * d->decay;
    }
    double dv = v_new - *velocity;
    dv = dv < -d->dv_limit ? -d->dv_limit : dv;
    dv = dv > d->dv_limit ? d->dv_limit : dv;
    v_new = settled(*velocity + dv);
    *position = *position + 0.5 * (*velocity + v_new) * period;
    *velocity = v_new;
    const double half = 0.5 * l->backlash;
    if (*position - *load > half)
        *load = *position - half;
    else if (*position - *load < -half)
        *load = *position + half;
    *measured = rint(*load / d->resolution) * d->resolution + noise;
    return error;
}

enum { L_P_REF, L_V_REF, L_A_REF, L_NOISE, L_POSITION, L_VELOCITY, L_LOAD, L_MEASURED, L_KP, L_VELOCITY_FF,
       L_ACCEL_GAIN, L_DECAY, L_V_LIMIT, L_DV_LIMIT, L_RESOLUTION, L_FRICTION, L_BACKLASH, L_OUT, L_ARRAYS };

static const char *const L_NAMES[L_ARRAYS] = {
    "p_ref", "v_ref", "a_ref", "noise", "position", "velocity", "load", "measured", "kp", "velocity_ff",
    "accel_gain", "decay", "v_limit", "dv_limit", "resolution", "friction", "backlash", "out"};

static PyObject *run_plant_py(PyObject *self, PyObject *args)
{
    PyObject *obj[L_ARRAYS];
    Py_buffer view[L_ARRAYS];
    double period;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOOOOOOOdO:run_plant", &obj[L_P_REF], &obj[L_V_REF], &obj[L_A_REF],
                          &obj[L_NOISE], &obj[L_POSITION], &obj[L_VELOCITY], &obj[L_LOAD], &obj[L_MEASURED],
                          &obj[L_KP], &obj[L_VELOCITY_FF], &obj[L_ACCEL_GAIN], &obj[L_DECAY], &obj[L_V_LIMIT],
                          &obj[L_DV_LIMIT], &obj[L_RESOLUTION], &obj[L_FRICTION], &obj[L_BACKLASH], &period,
                          &obj[L_OUT]))
        return NULL;
    int taken = take_all(obj, view, L_ARRAYS, 1UL << L_POSITION | 1UL << L_VELOCITY | 1UL << L_LOAD
                         | 1UL << L_MEASURED | 1UL << L_OUT, L_NAMES);
    Py_ssize_t rows, joints;
    int ok = taken == L_ARRAYS && check_sizes(view, L_NAMES, L_POSITION, L_OUT, &rows, &joints) == 0;
    Drive *drives = NULL;
    Losses *losses = NULL;
    if (ok) {
        const double *d[L_ARRAYS];
        for (int a = 0; a < L_ARRAYS; a++)
            d[a] = (const double *)view[a].buf;
        drives = PyMem_Malloc((size_t)joints * sizeof(Drive));
        losses = PyMem_Malloc((size_t)joints * sizeof(Losses));
        ok = drives != NULL && losses != NULL;
        if (!ok)
            PyErr_NoMemory();
        for (Py_ssize_t j = 0; ok && j < joints; j++) {
            drives[j] = (Drive){d[L_KP][j], d[L_VELOCITY_FF][j], d[L_ACCEL_GAIN][j], d[L_DECAY][j], d[L_V_LIMIT][j],
                                d[L_DV_LIMIT][j], d[L_RESOLUTION][j]};
            losses[j] = (Losses){d[L_FRICTION][j], d[L_BACKLASH][j]};
        }
        if (ok) {
            double *position = view[L_POSITION].buf, *velocity = view[L_VELOCITY].buf, *load = view[L_LOAD].buf;
            double *measured = view[L_MEASURED].buf, *out = view[L_OUT].buf;
            const Py_ssize_t plane = rows * joints;
            Py_BEGIN_ALLOW_THREADS
            for (Py_ssize_t k = 0; k < plane; k += joints)
                for (Py_ssize_t j = 0; j < joints; j++) {
                    out[k + j] = measured[j];
                    out[plane + k + j] = velocity[j];
                    out[2 * plane + k + j] = step_plant(&drives[j], &losses[j], period, d[L_P_REF][k + j],
                                                        d[L_V_REF][k + j], d[L_A_REF][k + j], d[L_NOISE][k + j],
                                                        &position[j], &velocity[j], &load[j], &measured[j]);
                }
            Py_END_ALLOW_THREADS
        }
    }
    PyMem_Free(drives);
    PyMem_Free(losses);
    for (int a = 0; a < taken; a++)
        PyBuffer_Release(&view[a]);
    if (!ok)
        return NULL;
    Py_RETURN_NONE;
}

/* An index array argument: C-contiguous int64. */
static int take_index(PyObject *obj, Py_buffer *view, const char *name)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return -1;
    if (view->itemsize != sizeof(Py_ssize_t) || view->format == NULL || strchr("qln", view->format[0]) == NULL) {
        PyErr_Format(PyExc_TypeError, "%s: expected an int64 array", name);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static PyObject *run_shared_py(PyObject *self, PyObject *args)
{
    PyObject *obj[ARRAYS], *index_obj[2];
    Py_buffer view[ARRAYS], index[2];
    Py_ssize_t depth;
    double period;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOnOOOOOOOOOOOOdO:run_shared", &obj[P_REF], &obj[V_REF], &obj[A_REF], &depth,
                          &index_obj[0], &index_obj[1], &obj[POSITION], &obj[VELOCITY], &obj[MEASURED], &obj[KP],
                          &obj[VELOCITY_FF], &obj[ACCEL_GAIN], &obj[DECAY], &obj[V_LIMIT], &obj[DV_LIMIT],
                          &obj[RESOLUTION], &period, &obj[OUT]))
        return NULL;
    int taken = take_all(obj, view, ARRAYS, 1UL << POSITION | 1UL << VELOCITY | 1UL << MEASURED | 1UL << OUT, NAMES);
    int indexed = 0;
    while (taken == ARRAYS && indexed < 2 && take_index(index_obj[indexed], &index[indexed],
                                                        indexed ? "delay" : "source") == 0)
        indexed++;
    int ok = taken == ARRAYS && indexed == 2 && depth >= 0;
    Py_ssize_t joints = ok ? values(&view[KP]) : 0, rows = 0, width = 0;
    const Py_ssize_t *source = ok ? index[0].buf : NULL, *delay = ok ? index[1].buf : NULL;
    if (ok) {  /* out fixes the rows, the sources their width; every column within them */
        rows = joints ? values(&view[OUT]) / (3 * joints) : 0;
        width = rows + depth ? values(&view[P_REF]) / (rows + depth) : 0;
        ok = joints > 0 && values(&view[OUT]) == 3 * rows * joints && width > 0
             && index[0].len == joints * (Py_ssize_t)sizeof(Py_ssize_t) && index[1].len == index[0].len;
        for (int x = P_REF; ok && x <= A_REF; x++)
            ok = values(&view[x]) == (rows + depth) * width;
        for (int x = POSITION; ok && x < OUT; x++)
            ok = values(&view[x]) == joints;
        for (Py_ssize_t j = 0; ok && j < joints; j++)
            ok = source[j] >= 0 && source[j] < width && delay[j] >= 0 && delay[j] <= depth;
        if (!ok)
            PyErr_SetString(PyExc_ValueError, "run_shared: sizes, sources or delays do not agree");
    }
    if (ok) {
        const double *d[ARRAYS];
        Drive *drives = drives_of(view, d, joints);
        ok = drives != NULL;
        if (ok) {
            Py_BEGIN_ALLOW_THREADS
            run_shared(rows, joints, width, depth, d[P_REF], d[V_REF], d[A_REF], source, delay,
                       (double *)view[POSITION].buf, (double *)view[VELOCITY].buf, (double *)view[MEASURED].buf,
                       drives, period, (double *)view[OUT].buf);
            Py_END_ALLOW_THREADS
        }
        PyMem_Free(drives);
    }
    for (int x = 0; x < indexed; x++)
        PyBuffer_Release(&index[x]);
    for (int x = 0; x < taken; x++)
        PyBuffer_Release(&view[x]);
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
    {"run_shared", run_shared_py, METH_VARARGS,
     "run_shared(p_src, v_src, a_src, depth, source, delay, position, velocity, measured, kp, velocity_ff,\n"
     "    accel_gain, decay, v_limit, dv_limit, resolution, period, out): run on references given once\n"
     "    per source ((depth + rows) x sources, the first depth rows still in transit): column j reads\n"
     "    source[j]'s, delay[j] rows earlier (int64 arrays); the error is against the reference as\n"
     "    commanded."},
    {"run_plant", run_plant_py, METH_VARARGS,
     "run_plant(p_ref, v_ref, a_ref, noise, position, velocity, load, measured, kp, velocity_ff, accel_gain,\n"
     "    decay, v_limit, dv_limit, resolution, friction, backlash, period, out): run with a plant's\n"
     "    friction, backlash and encoder noise (rows x joints, added to each reading)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_drive_kernel",
                                    "The servo drive model's compiled kernel (see drive.py).", -1, METHODS};

PyMODINIT_FUNC PyInit__drive_kernel(void)
{
    return PyModule_Create(&MODULE);
}
