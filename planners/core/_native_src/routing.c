/* The 2-opt of short tours (planners.core.routing). */
#include "native.h"

/* two_opt_small(dmat, route) -> list[int]: planners.core.routing._two_opt_small (first-improvement
 * 2-opt of an open path whose first node stays first). dmat: a C-contiguous (m, m) float64 buffer;
 * route: m node indices, route[0] == 0. Returns the visiting order without the start, minus one. */
PyObject *
two_opt_small(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "two_opt_small(dmat, route)");
        return NULL;
    }
    Py_buffer buf;
    if (PyObject_GetBuffer(args[0], &buf, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return NULL;
    PyObject *seq = PySequence_Fast(args[1], "route must be a sequence");
    if (seq == NULL) {
        PyBuffer_Release(&buf);
        return NULL;
    }
    Py_ssize_t m = PySequence_Fast_GET_SIZE(seq);
    if (buf.itemsize != 8 || buf.format == NULL || strcmp(buf.format, "d") != 0 || buf.len != m * m * 8) {
        PyErr_SetString(PyExc_ValueError, "dmat must be a (len(route), len(route)) float64 array");
        goto fail_early;
    }
    const double *d = (const double *)buf.buf;
    Py_ssize_t *path = PyMem_Malloc((m + 1) * sizeof(Py_ssize_t));
    double *edge = PyMem_Malloc((m + 1) * sizeof(double));
    if (path == NULL || edge == NULL) {
        PyMem_Free(path);
        PyMem_Free(edge);
        PyErr_NoMemory();
        goto fail_early;
    }
    for (Py_ssize_t k = 0; k < m; k++) {
        Py_ssize_t v = PyLong_AsSsize_t(PySequence_Fast_GET_ITEM(seq, k));
        if (v == -1 && PyErr_Occurred())
            goto fail;
        if (v < 0 || v >= m) {
            PyErr_SetString(PyExc_ValueError, "route index out of range");
            goto fail;
        }
        path[k] = v;
    }
    Py_ssize_t n = m - 1;
#define D(i, j) d[(i) * m + (j)]
    for (Py_ssize_t k = 0; k < n; k++)
        edge[k] = D(path[k], path[k + 1]);
    int improved = 1;
    while (improved) {
        improved = 0;
        for (Py_ssize_t i = 1; i < n; i++) {
            Py_ssize_t a = path[i - 1], b = path[i];
            double dab = edge[i - 1];
            for (Py_ssize_t j = i + 1; j < n; j++) {
                Py_ssize_t e = path[j + 1];
                if (dab + edge[j] - D(a, path[j]) - D(b, e) > 1e-9) {
                    for (Py_ssize_t lo = i, hi = j; lo < hi; lo++, hi--) {
                        Py_ssize_t t = path[lo]; path[lo] = path[hi]; path[hi] = t;
                    }
                    for (Py_ssize_t lo = i, hi = j - 1; lo < hi; lo++, hi--) {
                        double t = edge[lo]; edge[lo] = edge[hi]; edge[hi] = t;
                    }
                    b = path[i];
                    dab = edge[i - 1] = D(a, b);
                    edge[j] = D(path[j], e);
                    improved = 1;
                }
            }
            if (dab - D(a, path[n]) > 1e-9) {
                for (Py_ssize_t lo = i, hi = n; lo < hi; lo++, hi--) {
                    Py_ssize_t t = path[lo]; path[lo] = path[hi]; path[hi] = t;
                }
                for (Py_ssize_t lo = i, hi = n - 1; lo < hi; lo++, hi--) {
                    double t = edge[lo]; edge[lo] = edge[hi]; edge[hi] = t;
                }
                edge[i - 1] = D(a, path[i]);
                improved = 1;
            }
        }
    }
#undef D
    PyObject *out = PyList_New(n > 0 ? n : 0);
    if (out == NULL)
        goto fail;
    for (Py_ssize_t k = 1; k <= n; k++) {
        PyObject *v = PyLong_FromSsize_t(path[k] - 1);
        if (v == NULL) {
            Py_DECREF(out);
            goto fail;
        }
        PyList_SET_ITEM(out, k - 1, v);
    }
    PyMem_Free(path);
    PyMem_Free(edge);
    Py_DECREF(seq);
    PyBuffer_Release(&buf);
    return out;
fail:
    PyMem_Free(path);
    PyMem_Free(edge);
fail_early:
    Py_DECREF(seq);
    PyBuffer_Release(&buf);
    return NULL;
}
