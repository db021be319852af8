/* Reach regions (planners.collect.reach): projections, circle crossings, vertices, clipping,
 * the farthest flight; CPython's math.hypot as a function. */
#include "native.h"

/* farthest_flight(rows, p): Region.farthest_flight; farthest_of: the longest flight from (x, y) to
 * the rows (x, y, z2) */
int
farthest_of(PyObject *rows_obj, double x, double y, double *out)
{
    PyObject *rows = PySequence_Fast(rows_obj, "rows must be a sequence of (x, y, z2)");
    if (rows == NULL)
        return -1;
    double worst = 0.0;
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(rows); i++) {
        PyObject *r = PySequence_Fast_GET_ITEM(rows, i);
        double gx, gy, z2;
        if (item_double(r, 0, &gx) < 0 || item_double(r, 1, &gy) < 0 || item_double(r, 2, &z2) < 0) {
            Py_DECREF(rows);
            return -1;
        }
        double d2 = (x - gx) * (x - gx) + (y - gy) * (y - gy) + z2;
        if (d2 > worst)
            worst = d2;
    }
    Py_DECREF(rows);
    *out = sqrt(worst);
    return 0;
}

PyObject *
farthest_flight(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "farthest_flight(rows, p)");
        return NULL;
    }
    double x, y, far;
    if (item_double(args[1], 0, &x) < 0 || item_double(args[1], 1, &y) < 0
        || farthest_of(args[0], x, y, &far) < 0)
        return NULL;
    return PyFloat_FromDouble(far);
}

PyObject *
hypot_(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double x, y;
    if (nargs != 2 || as_double(args[0], &x) < 0 || as_double(args[1], &y) < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "hypot(x, y)");
        return NULL;
    }
    return PyFloat_FromDouble(py_hypot(x, y));
}


typedef struct { double neg; Py_ssize_t i; double n; } Violation;

/* project_discs(discs, limits, x, y): planners.collect.reach.project_discs, the nearest point of the
 * discs' intersection to (x, y) when it lies on one circle, else the index of the disc (x, y)
 * violates most (the caller then looks at the vertices) */
PyObject *
project_discs(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double x, y;
    if (nargs != 4 || as_double(args[2], &x) < 0 || as_double(args[3], &y) < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "project_discs(discs, limits, x, y)");
        return NULL;
    }
    PyObject *discs = PySequence_Fast(args[0], "discs must be a sequence");
    if (discs == NULL)
        return NULL;
    PyObject *limits = NULL, *out = NULL;
    Violation stack[32], *v = stack;
    Py_ssize_t k = PySequence_Fast_GET_SIZE(discs);
    double cx, cy, r;
    if (k == 1) {
        if (triple(PySequence_Fast_GET_ITEM(discs, 0), &cx, &cy, &r) < 0)
            goto done;
        double n = py_hypot(x - cx, y - cy);
        out = n <= r ? point(x, y) : point(cx + (x - cx) * r / n, cy + (y - cy) * r / n);
        goto done;
    }
    limits = PySequence_Fast(args[1], "limits must be a sequence");
    if (limits == NULL)
        goto done;
    if (k > 32 && (v = PyMem_Malloc(k * sizeof(Violation))) == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t m = 0;
    for (Py_ssize_t i = 0; i < k; i++) {
        if (triple(PySequence_Fast_GET_ITEM(discs, i), &cx, &cy, &r) < 0)
            goto done;
        double n = py_hypot(x - cx, y - cy);
        if (n > r + INSIDE_TOL) {  /* insertion in (neg, i) order: Python's sort of the tuples */
            Violation e = {r - n, i, n};
            Py_ssize_t j = m++;
            while (j > 0 && v[j - 1].neg > e.neg) {
                v[j] = v[j - 1];
                j--;
            }
            v[j] = e;
        }
    }
    if (m == 0) {
        out = point(x, y);
        goto done;
    }
    double least = v[0].neg;
    Py_ssize_t nl = PySequence_Fast_GET_SIZE(limits);
    for (Py_ssize_t t = 0; t < m; t++) {
        if (-v[t].neg < -least - 1e-9)
            break;
        if (triple(PySequence_Fast_GET_ITEM(discs, v[t].i), &cx, &cy, &r) < 0)
            goto done;
        double n = v[t].n;
        double qx = cx + (x - cx) * r / n, qy = cy + (y - cy) * r / n;
        int inside = 1;
        for (Py_ssize_t g = 0; g < nl; g++) {
            double gx, gy, lim;
            if (triple(PySequence_Fast_GET_ITEM(limits, g), &gx, &gy, &lim) < 0)
                goto done;
            if (py_square(qx - gx) + py_square(qy - gy) > lim) {
                inside = 0;
                break;
            }
        }
        if (inside) {
            out = point(qx, qy);
            goto done;
        }
    }
    out = PyLong_FromSsize_t(v[0].i);
done:
    if (v != stack)
        PyMem_Free(v);
    Py_XDECREF(limits);
    Py_DECREF(discs);
    return out;
}

/* _pair_points: the two crossings of two circles (x, y, rho), or 0 when they do not cross */
static int
pair_points(double xi, double yi, double ri, double xj, double yj, double rj, double q[4])
{
    double dx = xj - xi, dy = yj - yi;
    double dist = py_hypot(dx, dy);
    if (!(dist > 1e-12 && dist <= ri + rj + INSIDE_TOL && dist >= fabs(ri - rj) - INSIDE_TOL))
        return 0;
    double a = (ri * ri - rj * rj + dist * dist) / (2.0 * dist);
    double h2 = ri * ri - a * a;
    double h = sqrt(0.0 > h2 ? 0.0 : h2);
    double ux = dx / dist, uy = dy / dist;
    double bx = xi + a * ux, by = yi + a * uy;
    double px = -uy * h, py = ux * h;
    q[0] = bx + px; q[1] = by + py; q[2] = bx - px; q[3] = by - py;
    return 1;
}

/* rim(disc, discs, limits): planners.collect.reach.rim, the crossings of disc's circle with every
 * other that lie in the intersection, each as ((x, y), other disc) */
PyObject *
rim(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "rim(disc, discs, limits)");
        return NULL;
    }
    double xi, yi, ri;
    if (triple(args[0], &xi, &yi, &ri) < 0)
        return NULL;
    PyObject *discs = PySequence_Fast(args[1], "discs must be a sequence");
    if (discs == NULL)
        return NULL;
    PyObject *limits = PySequence_Fast(args[2], "limits must be a sequence");
    PyObject *out = limits ? PyList_New(0) : NULL;
    if (out == NULL)
        goto fail;
    Py_ssize_t nl = PySequence_Fast_GET_SIZE(limits);
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(discs); i++) {
        PyObject *d2 = PySequence_Fast_GET_ITEM(discs, i);
        if (d2 == args[0])
            continue;
        double xj, yj, rj, q[4];
        if (triple(d2, &xj, &yj, &rj) < 0)
            goto fail;
        if (!pair_points(xi, yi, ri, xj, yj, rj, q))
            continue;
        for (int t = 0; t < 2; t++) {
            double x = q[2 * t], y = q[2 * t + 1];
            int inside = 1;
            for (Py_ssize_t g = 0; g < nl; g++) {
                double cx, cy, lim;
                if (triple(PySequence_Fast_GET_ITEM(limits, g), &cx, &cy, &lim) < 0)
                    goto fail;
                if (py_square(x - cx) + py_square(y - cy) > lim) {
                    inside = 0;
                    break;
                }
            }
            if (!inside)
                continue;
            PyObject *pt = point(x, y);
            PyObject *entry = pt ? PyTuple_Pack(2, pt, d2) : NULL;
            Py_XDECREF(pt);
            if (entry == NULL || PyList_Append(out, entry) < 0) {
                Py_XDECREF(entry);
                goto fail;
            }
            Py_DECREF(entry);
        }
    }
    Py_DECREF(limits);
    Py_DECREF(discs);
    return out;
fail:
    Py_XDECREF(out);
    Py_XDECREF(limits);
    Py_DECREF(discs);
    return NULL;
}

/* disc_vertices(discs): planners.collect.reach.disc_vertices, every pair's crossings (all first
 * points, then all second points) that lie inside every disc */
PyObject *
disc_vertices(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 1) {
        PyErr_SetString(PyExc_TypeError, "disc_vertices(discs)");
        return NULL;
    }
    PyObject *seq = PySequence_Fast(args[0], "discs must be a sequence");
    if (seq == NULL)
        return NULL;
    Py_ssize_t k = PySequence_Fast_GET_SIZE(seq), found = 0;
    double *d = PyMem_Malloc((size_t)(3 * k + 2 * k * k + 1) * sizeof(double));
    PyObject *out = d ? PyList_New(0) : PyErr_NoMemory();
    if (out == NULL)
        goto fail;
    for (Py_ssize_t i = 0; i < k; i++)
        if (triple(PySequence_Fast_GET_ITEM(seq, i), &d[3 * i], &d[3 * i + 1], &d[3 * i + 2]) < 0)
            goto fail;
    double *plus = d + 3 * k, *minus = plus + k * k;  /* at most k(k-1)/2 pairs each */
    for (Py_ssize_t i = 0; i < k; i++)
        for (Py_ssize_t j = i + 1; j < k; j++) {
            double q[4];
            if (pair_points(d[3 * i], d[3 * i + 1], d[3 * i + 2], d[3 * j], d[3 * j + 1], d[3 * j + 2], q)) {
                plus[2 * found] = q[0], plus[2 * found + 1] = q[1];
                minus[2 * found] = q[2], minus[2 * found + 1] = q[3];
                found++;
            }
        }
    for (int half = 0; half < 2; half++)
        for (Py_ssize_t t = 0; t < found; t++) {
            double x = (half ? minus : plus)[2 * t], y = (half ? minus : plus)[2 * t + 1];
            int inside = 1;
            for (Py_ssize_t g = 0; g < k && inside; g++)
                inside = !(py_hypot(x - d[3 * g], y - d[3 * g + 1]) > d[3 * g + 2] + INSIDE_TOL);
            if (!inside)
                continue;
            PyObject *pt = point(x, y);
            if (pt == NULL || PyList_Append(out, pt) < 0) {
                Py_XDECREF(pt);
                goto fail;
            }
            Py_DECREF(pt);
        }
    PyMem_Free(d);
    Py_DECREF(seq);
    return out;
fail:
    PyMem_Free(d);
    Py_XDECREF(out);
    Py_DECREF(seq);
    return NULL;
}

/* vertex_on_rim(rim, disc, x, y): planners.collect.reach.vertex_on_rim, the vertex of the circle
 * `disc` nearest to (x, y) when it is the region's nearest point, else None */
PyObject *
vertex_on_rim(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double xm, ym, rm, x, y;
    if (nargs != 4 || triple(args[1], &xm, &ym, &rm) < 0 || as_double(args[2], &x) < 0
        || as_double(args[3], &y) < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "vertex_on_rim(rim, disc, x, y)");
        return NULL;
    }
    PyObject *seq = PySequence_Fast(args[0], "rim must be a sequence");
    if (seq == NULL)
        return NULL;
    PyObject *best = NULL, *other = args[1];
    double least = INFINITY, vx = 0.0, vy = 0.0;
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(seq); i++) {
        PyObject *entry = PySequence_Fast_GET_ITEM(seq, i);
        if (!PyTuple_Check(entry) || PyTuple_GET_SIZE(entry) != 2) {
            PyErr_SetString(PyExc_TypeError, "rim entries are ((x, y), disc)");
            Py_DECREF(seq);
            return NULL;
        }
        PyObject *q = PyTuple_GET_ITEM(entry, 0);
        double qx, qy;
        if (item_double(q, 0, &qx) < 0 || item_double(q, 1, &qy) < 0) {
            Py_DECREF(seq);
            return NULL;
        }
        double dq = py_hypot(qx - x, qy - y);
        if (dq < least)
            best = q, other = PyTuple_GET_ITEM(entry, 1), least = dq, vx = qx, vy = qy;
    }
    double ox, oy, orad;
    if (best == NULL || triple(other, &ox, &oy, &orad) < 0) {
        Py_DECREF(seq);
        if (PyErr_Occurred())
            return NULL;
        Py_RETURN_NONE;
    }
    double a1x = vx - xm, a1y = vy - ym;
    double a2x = vx - ox, a2y = vy - oy;
    double det = a1x * a2y - a1y * a2x;
    double size = py_hypot(a1x, a1y) * py_hypot(a2x, a2y);
    PyObject *out = Py_None;
    if (!(fabs(det) < 1e-12 * (size > 1.0 ? size : 1.0))) {
        double px = x - vx, py = y - vy;
        double lam1 = (px * a2y - py * a2x) / det;
        double lam2 = (a1x * py - a1y * px) / det;
        if (lam1 >= -1e-9 && lam2 >= -1e-9)
            out = best;
    }
    Py_INCREF(out);
    Py_DECREF(seq);
    return out;
}

/* clip_segment(discs, a, b): planners.collect.reach.clip_segment, the parameters [s0, s1] of the
 * part of segment a -> b inside every disc, or None */
PyObject *
clip_segment(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "clip_segment(discs, a, b)");
        return NULL;
    }
    double ax, ay, bx, by;
    if (item_double(args[1], 0, &ax) < 0 || item_double(args[1], 1, &ay) < 0
        || item_double(args[2], 0, &bx) < 0 || item_double(args[2], 1, &by) < 0)
        return NULL;
    PyObject *discs = PySequence_Fast(args[0], "discs must be a sequence");
    if (discs == NULL)
        return NULL;
    double dx = bx - ax, dy = by - ay;
    double qa = dx * dx + dy * dy;
    double lo = 0.0, hi = 1.0;
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(discs); i++) {
        double cx, cy, r;
        if (triple(PySequence_Fast_GET_ITEM(discs, i), &cx, &cy, &r) < 0) {
            Py_DECREF(discs);
            return NULL;
        }
        double ex = ax - cx, ey = ay - cy;
        double qc = ex * ex + ey * ey - r * r;
        if (qa < 1e-18) {
            if (qc > 0)
                goto none;
            continue;
        }
        double qb = 2.0 * (dx * ex + dy * ey);
        double disc = qb * qb - 4.0 * qa * qc;
        if (disc < 0)
            goto none;
        double sq = sqrt(disc);
        double s0 = (-qb - sq) / (2.0 * qa);
        if (s0 > lo)
            lo = s0;
        double s1 = (-qb + sq) / (2.0 * qa);
        if (s1 < hi)
            hi = s1;
        if (lo > hi)
            goto none;
    }
    Py_DECREF(discs);
    return point(lo, hi);
none:
    Py_DECREF(discs);
    Py_RETURN_NONE;
}
