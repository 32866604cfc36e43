/* Array arguments of the planner's compiled kernels (motion/_sample_kernel.c,
 * kinds/drill/_lag_kernel.c, kinds/thread/_stock_kernel.c and _helix_kernel.c), through the
 * buffer protocol: float64 ("d") or intp ("l") arrays of one or two dimensions, any strides
 * (a plan's columns are strided). */
#ifndef CNC_PLANNER_KERNEL_BUFFERS_H
#define CNC_PLANNER_KERNEL_BUFFERS_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

/* One array argument of the given format. */
static int take(PyObject *obj, Py_buffer *view, int writable, const char *format, const char *name)
{
    int flags = PyBUF_STRIDES | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0)
        return -1;
    if (view->ndim > 2 || view->format == NULL || strcmp(view->format, format) != 0) {
        PyErr_Format(PyExc_TypeError, "%s: expected an array of format '%s'", name, format);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* The arguments' buffers: obj[k] into view[k], integer ("l") where formats[k] is 'l',
 * writable from index ``writable`` on; how many were taken (all, or an error is set). */
static int take_all(PyObject **obj, Py_buffer *view, int count, const char *formats, int writable,
                    const char *const *names)
{
    int taken = 0;
    while (taken < count) {
        const char format[2] = {formats[taken], 0};
        if (take(obj[taken], &view[taken], taken >= writable, format, names[taken]) < 0)
            break;
        taken++;
    }
    return taken;
}

/* Release the buffers taken; None, or NULL with the error set when not ok. */
static PyObject *finish(Py_buffer *view, int taken, int ok)
{
    for (int k = 0; k < taken; k++)
        PyBuffer_Release(&view[k]);
    if (!ok)
        return NULL;
    Py_RETURN_NONE;
}

/* Element i of a one-dimensional view, or row i of a two-dimensional one's column c. */
#define AT(view, type, i) (*(type *)((char *)(view).buf + (i) * (view).strides[0]))
#define AT2(view, type, i, c) (*(type *)((char *)(view).buf + (i) * (view).strides[0] + (c) * (view).strides[1]))

#endif
