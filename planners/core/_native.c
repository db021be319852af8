/* Optional compiled kernels of the planners' innermost loops (issue: planner speed at scale).
 *
 * Every function here is the C twin of a pure-Python function named in its comment, with the
 * same floating-point operations in the same order (the build turns off contraction into fused
 * multiply-adds, -ffp-contract=off), so that a plan is the same float for float with or without
 * this module. planners/core/native.py loads it when the install could compile it and falls back
 * to the Python functions otherwise; tests compare both on random inputs. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stddef.h>
#include <float.h>
#include <stdlib.h>
#include <string.h>

/* two_opt_small(dmat, route) -> list[int]: planners.core.routing._two_opt_small (first-improvement
 * 2-opt of an open path whose first node stays first). dmat: a C-contiguous (m, m) float64 buffer;
 * route: m node indices, route[0] == 0. Returns the visiting order without the start, minus one. */
static PyObject *
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


/* ---- the time model's carrier hop and rover leg (planners.core.timing) ---- */

static const double TAU = 6.283185307179586;  /* math.tau */

/* Python's float %: the sign of the divisor (here tau > 0) */
static inline double
py_mod_tau(double x)
{
    double mod = fmod(x, TAU);
    if (mod != 0.0) {
        if (mod < 0.0)
            mod += TAU;
    }
    else {
        mod = 0.0;
    }
    return mod;
}

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    double v, a, w, ramp, brake;
    int has_a, has_w;
} StepperObject;

/* carrier_stepper's step(dx, dy, heading) -> (t, heading after) */
static PyObject *
step_values(StepperObject *s, double dx, double dy, double heading, PyObject *heading_obj)
{
    double d2 = dx * dx + dy * dy;
    if (d2 <= 1e-18) {
        PyObject *zero = PyFloat_FromDouble(0.0);
        if (zero == NULL)
            return NULL;
        Py_INCREF(heading_obj);
        PyObject *out = PyTuple_Pack(2, zero, heading_obj);
        Py_DECREF(zero);
        Py_DECREF(heading_obj);
        return out;
    }
    double h = atan2(dy, dx);
    double length = sqrt(d2);
    double t;
    if (!s->has_a)
        t = length / s->v;
    else if (length >= s->ramp)
        t = length / s->v + s->brake;
    else
        t = 2.0 * sqrt(length / s->a);
    if (s->has_w) {
        double turn = py_mod_tau(h - heading);
        double other = TAU - turn;
        t += (turn <= other ? turn : other) / s->w;
    }
    PyObject *pt = PyFloat_FromDouble(t), *ph = PyFloat_FromDouble(h);
    PyObject *out = (pt && ph) ? PyTuple_Pack(2, pt, ph) : NULL;
    Py_XDECREF(pt);
    Py_XDECREF(ph);
    return out;
}

static int
as_double(PyObject *o, double *x)
{
    *x = PyFloat_Check(o) ? PyFloat_AS_DOUBLE(o) : PyFloat_AsDouble(o);
    return (*x == -1.0 && PyErr_Occurred()) ? -1 : 0;
}

static int
item_double(PyObject *seq, Py_ssize_t i, double *x)
{
    if (PyTuple_CheckExact(seq) && i < PyTuple_GET_SIZE(seq))
        return as_double(PyTuple_GET_ITEM(seq, i), x);
    if (PyList_CheckExact(seq) && i < PyList_GET_SIZE(seq))
        return as_double(PyList_GET_ITEM(seq, i), x);
    PyObject *o = PySequence_GetItem(seq, i);
    if (o == NULL)
        return -1;
    int r = as_double(o, x);
    Py_DECREF(o);
    return r;
}

static PyObject *
stepper_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    if (nargs != 3 || (kwnames && PyTuple_GET_SIZE(kwnames))) {
        PyErr_SetString(PyExc_TypeError, "step(dx, dy, heading)");
        return NULL;
    }
    double dx, dy, hd;
    if (as_double(args[0], &dx) < 0 || as_double(args[1], &dy) < 0 || as_double(args[2], &hd) < 0)
        return NULL;
    return step_values((StepperObject *)self, dx, dy, hd, args[2]);
}

/* carrier_hopper's hop(p, q, heading): step(q[0] - p[0], q[1] - p[1], heading) */
static PyObject *
hopper_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    if (nargs != 3 || (kwnames && PyTuple_GET_SIZE(kwnames))) {
        PyErr_SetString(PyExc_TypeError, "hop(p, q, heading)");
        return NULL;
    }
    double px, py, qx, qy, hd;
    if (item_double(args[0], 0, &px) < 0 || item_double(args[0], 1, &py) < 0
        || item_double(args[1], 0, &qx) < 0 || item_double(args[1], 1, &qy) < 0
        || as_double(args[2], &hd) < 0)
        return NULL;
    return step_values((StepperObject *)self, qx - px, qy - py, hd, args[2]);
}

static int
optional_double(PyObject *o, double *x, int *has)
{
    *has = o != Py_None;
    return *has ? as_double(o, x) : 0;
}

static PyObject *
stepper_new_with(PyTypeObject *type, PyObject *args, vectorcallfunc call)
{
    PyObject *v, *a, *w;
    if (!PyArg_ParseTuple(args, "OOO", &v, &a, &w))
        return NULL;
    StepperObject *s = (StepperObject *)type->tp_alloc(type, 0);
    if (s == NULL)
        return NULL;
    s->vectorcall = call;
    if (as_double(v, &s->v) < 0 || optional_double(a, &s->a, &s->has_a) < 0
        || optional_double(w, &s->w, &s->has_w) < 0) {
        Py_DECREF(s);
        return NULL;
    }
    if (s->has_a) {  /* the Python closure's v * v / a and v / a, computed once */
        s->ramp = s->v * s->v / s->a;
        s->brake = s->v / s->a;
    }
    return (PyObject *)s;
}

static PyObject *
stepper_new(PyTypeObject *type, PyObject *args, PyObject *kw)
{
    return stepper_new_with(type, args, stepper_call);
}

static PyObject *
hopper_new(PyTypeObject *type, PyObject *args, PyObject *kw)
{
    return stepper_new_with(type, args, hopper_call);
}

static PyTypeObject StepperType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Stepper",
    .tp_doc = "Stepper(max_speed, accel|None, turn_rate|None): carrier_stepper's step(dx, dy, heading)",
    .tp_basicsize = sizeof(StepperObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(StepperObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_new = stepper_new,
};

static PyTypeObject HopperType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Hopper",
    .tp_doc = "Hopper(max_speed, accel|None, turn_rate|None): carrier_hopper's hop(p, q, heading)",
    .tp_basicsize = sizeof(StepperObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(StepperObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_new = hopper_new,
};

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    double v, a, fixed, ramp, brake;
    int has_a;
} LegObject;

/* leg_timer's leg(length) */
static PyObject *
leg_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    LegObject *l = (LegObject *)self;
    if (PyVectorcall_NARGS(nargsf) != 1 || (kwnames && PyTuple_GET_SIZE(kwnames))) {
        PyErr_SetString(PyExc_TypeError, "leg(length)");
        return NULL;
    }
    double length;
    if (as_double(args[0], &length) < 0)
        return NULL;
    double t;
    if (length <= 0.0)
        t = l->fixed + 0.0;
    else if (!l->has_a)
        t = l->fixed + length / l->v;
    else if (length >= l->ramp)
        t = l->fixed + (length / l->v + l->brake);
    else
        t = l->fixed + 2.0 * sqrt(length / l->a);
    return PyFloat_FromDouble(t);
}

static PyObject *
leg_new(PyTypeObject *type, PyObject *args, PyObject *kw)
{
    PyObject *v, *a, *fixed;
    if (!PyArg_ParseTuple(args, "OOO", &v, &a, &fixed))
        return NULL;
    LegObject *l = (LegObject *)type->tp_alloc(type, 0);
    if (l == NULL)
        return NULL;
    l->vectorcall = leg_call;
    if (as_double(v, &l->v) < 0 || optional_double(a, &l->a, &l->has_a) < 0 || as_double(fixed, &l->fixed) < 0) {
        Py_DECREF(l);
        return NULL;
    }
    if (l->has_a) {
        l->ramp = l->v * l->v / l->a;
        l->brake = l->v / l->a;
    }
    return (PyObject *)l;
}

static PyTypeObject LegType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Leg",
    .tp_doc = "Leg(max_speed, accel|None, fixed_time): leg_timer's leg(length)",
    .tp_basicsize = sizeof(LegObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(LegObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_new = leg_new,
};

/* ---- reach regions (planners.collect.reach) ---- */

/* farthest_flight(rows, p): Region.farthest_flight over rows [(x, y, z2), ...] of floats */
static PyObject *
farthest_flight(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "farthest_flight(rows, p)");
        return NULL;
    }
    double x, y;
    if (item_double(args[1], 0, &x) < 0 || item_double(args[1], 1, &y) < 0)
        return NULL;
    PyObject *rows = PySequence_Fast(args[0], "rows must be a sequence of (x, y, z2)");
    if (rows == NULL)
        return NULL;
    double worst = 0.0;
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(rows); i++) {
        PyObject *r = PySequence_Fast_GET_ITEM(rows, i);
        double gx, gy, z2;
        if (item_double(r, 0, &gx) < 0 || item_double(r, 1, &gy) < 0 || item_double(r, 2, &z2) < 0) {
            Py_DECREF(rows);
            return NULL;
        }
        double d2 = (x - gx) * (x - gx) + (y - gy) * (y - gy) + z2;
        if (d2 > worst)
            worst = d2;
    }
    Py_DECREF(rows);
    return PyFloat_FromDouble(sqrt(worst));
}

/* ---- CPython's math.hypot for two numbers (Modules/mathmodule.c, vector_norm): correctly rounded in
 * nearly every case, and not the C library's hypot; the same algorithm gives the same float ---- */

typedef struct { double hi, lo; } DoubleLength;

static inline DoubleLength
dl_fast_sum(double a, double b)
{
    double x = a + b;
    double z = x - a;
    double y = b - z;
    return (DoubleLength){x, y};
}

static inline DoubleLength
dl_mul(double x, double y)
{
    /* the exact product as hi + lo (CPython: fma or Dekker's split, the same exact pair) */
    double z = x * y;
    double zz = fma(x, y, -z);
    return (DoubleLength){z, zz};
}

static double
vector_norm2(double a, double b, double max)
{
    if (isinf(max))
        return max;
    if (isnan(a) || isnan(b))
        return NAN;
    if (max == 0.0)
        return max;
    int max_e;
    frexp(max, &max_e);
    if (max_e < -1023) {  /* subnormals: CPython scales them up first */
        return DBL_MIN * vector_norm2(a / DBL_MIN, b / DBL_MIN, max / DBL_MIN);
    }
    double scale = ldexp(1.0, -max_e);
    double csum = 1.0, frac1 = 0.0, frac2 = 0.0;
    double vec[2] = {a, b};
    for (int i = 0; i < 2; i++) {
        double x = vec[i] * scale;
        DoubleLength pr = dl_mul(x, x);
        DoubleLength sm = dl_fast_sum(csum, pr.hi);
        csum = sm.hi;
        frac1 += pr.lo;
        frac2 += sm.lo;
    }
    double h = sqrt(csum - 1.0 + (frac1 + frac2));
    DoubleLength pr = dl_mul(-h, h);
    DoubleLength sm = dl_fast_sum(csum, pr.hi);
    csum = sm.hi;
    frac1 += pr.lo;
    frac2 += sm.lo;
    double x = csum - 1.0 + (frac1 + frac2);
    h += x / (2.0 * h);
    return h / scale;
}

static inline double
py_hypot(double x, double y)
{
    double a = fabs(x), b = fabs(y);
    double max = a > b ? a : b;  /* (NaN handled in vector_norm2) */
    if (isnan(a) || isnan(b))
        return isinf(max) ? max : NAN;
    return vector_norm2(a, b, max);
}

static PyObject *
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

static PyObject *
point(double x, double y)
{
    PyObject *px = PyFloat_FromDouble(x), *py = PyFloat_FromDouble(y);
    PyObject *out = (px && py) ? PyTuple_Pack(2, px, py) : NULL;
    Py_XDECREF(px);
    Py_XDECREF(py);
    return out;
}

static int
triple(PyObject *t, double *a, double *b, double *c)
{
    return (item_double(t, 0, a) < 0 || item_double(t, 1, b) < 0 || item_double(t, 2, c) < 0) ? -1 : 0;
}

/* Python's x ** 2: the C library's pow(x, 2.0), which is not always x * x; called through a
 * pointer the compiler cannot see through, so that it does not turn it into x * x */
static double (*volatile pow_fn)(double, double) = pow;

static inline double
py_square(double x)
{
    return pow_fn(x, 2.0);
}

#define INSIDE_TOL 1e-9  /* planners.collect.reach.INSIDE_TOL */

typedef struct { double neg; Py_ssize_t i; double n; } Violation;

/* project_discs(discs, limits, x, y): planners.collect.reach.project_discs, the nearest point of the
 * discs' intersection to (x, y) when it lies on one circle, else the index of the disc (x, y)
 * violates most (the caller then looks at the vertices) */
static PyObject *
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
static PyObject *
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

/* clip_segment(discs, a, b): planners.collect.reach.clip_segment, the parameters [s0, s1] of the
 * part of segment a -> b inside every disc, or None */
static PyObject *
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

static PyMethodDef methods[] = {
    {"two_opt_small", (PyCFunction)(void (*)(void))two_opt_small, METH_FASTCALL,
     "planners.core.routing._two_opt_small over a float64 distance matrix (the same tour)."},
    {"farthest_flight", (PyCFunction)(void (*)(void))farthest_flight, METH_FASTCALL,
     "planners.collect.reach.Region.farthest_flight over its rows (the same float)."},
    {"hypot", (PyCFunction)(void (*)(void))hypot_, METH_FASTCALL,
     "math.hypot(x, y) as CPython computes it (the kernels' distances)."},
    {"project_discs", (PyCFunction)(void (*)(void))project_discs, METH_FASTCALL,
     "planners.collect.reach.project_discs (the same floats)."},
    {"rim", (PyCFunction)(void (*)(void))rim, METH_FASTCALL,
     "planners.collect.reach.rim (the same floats)."},
    {"clip_segment", (PyCFunction)(void (*)(void))clip_segment, METH_FASTCALL,
     "planners.collect.reach.clip_segment (the same floats)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "planners.core._native",
    "Compiled twins of the planners' innermost loops (planners.core.native).", -1, methods,
};

PyMODINIT_FUNC
PyInit__native(void)
{
    if (PyType_Ready(&StepperType) < 0 || PyType_Ready(&HopperType) < 0 || PyType_Ready(&LegType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL)
        return NULL;
    if (PyModule_AddObjectRef(m, "Stepper", (PyObject *)&StepperType) < 0
        || PyModule_AddObjectRef(m, "Hopper", (PyObject *)&HopperType) < 0
        || PyModule_AddObjectRef(m, "Leg", (PyObject *)&LegType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
