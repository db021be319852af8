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

/* carrier_stepper's step: the time of the hop (dx, dy) from *heading, which becomes the heading
 * on arrival (unchanged on a hop of no length) */
static inline double
step_time(const StepperObject *s, double dx, double dy, double *heading)
{
    double d2 = dx * dx + dy * dy;
    if (d2 <= 1e-18)
        return 0.0;
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
        double turn = py_mod_tau(h - *heading);
        double other = TAU - turn;
        t += (turn <= other ? turn : other) / s->w;
    }
    *heading = h;
    return t;
}

/* carrier_stepper's step(dx, dy, heading) -> (t, heading after) */
static PyObject *
step_values(StepperObject *s, double dx, double dy, double heading, PyObject *heading_obj)
{
    double h = heading;
    double t = step_time(s, dx, dy, &h);
    PyObject *pt = PyFloat_FromDouble(t);
    PyObject *ph = dx * dx + dy * dy <= 1e-18 ? Py_NewRef(heading_obj) : PyFloat_FromDouble(h);
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
static inline double
leg_time(const LegObject *l, double length)
{
    if (length <= 0.0)
        return l->fixed + 0.0;
    if (!l->has_a)
        return l->fixed + length / l->v;
    if (length >= l->ramp)
        return l->fixed + (length / l->v + l->brake);
    return l->fixed + 2.0 * sqrt(length / l->a);
}

static PyObject *
leg_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    if (PyVectorcall_NARGS(nargsf) != 1 || (kwnames && PyTuple_GET_SIZE(kwnames))) {
        PyErr_SetString(PyExc_TypeError, "leg(length)");
        return NULL;
    }
    double length;
    if (as_double(args[0], &length) < 0)
        return NULL;
    return PyFloat_FromDouble(leg_time((LegObject *)self, length));
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
/* the longest flight from (x, y) to the rows (x, y, z2) */
static int
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

static PyObject *
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

/* disc_vertices(discs): planners.collect.reach.disc_vertices, every pair's crossings (all first
 * points, then all second points) that lie inside every disc */
static PyObject *
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
static PyObject *
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

/* ---- the collection's quick placement (planners.collect.path) ---- */

/* score_candidates(step, cands, prev, heading, nxt): planners.collect.path.score_candidates, per
 * candidate stop (stop, hop time into it, heading there, hop time on to nxt or None) */
static PyObject *
score_candidates(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double px, py, heading, nx = 0.0, ny = 0.0;
    if (nargs != 5 || Py_TYPE(args[0]) != &StepperType) {
        PyErr_SetString(PyExc_TypeError, "score_candidates(step: Stepper, cands, prev, heading, nxt)");
        return NULL;
    }
    StepperObject *s = (StepperObject *)args[0];
    int has_next = args[4] != Py_None;
    if (item_double(args[2], 0, &px) < 0 || item_double(args[2], 1, &py) < 0 || as_double(args[3], &heading) < 0
        || (has_next && (item_double(args[4], 0, &nx) < 0 || item_double(args[4], 1, &ny) < 0)))
        return NULL;
    PyObject *cands = PySequence_Fast(args[1], "cands must be a sequence of points");
    if (cands == NULL)
        return NULL;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(cands);
    PyObject *out = PyTuple_New(n);
    for (Py_ssize_t i = 0; out != NULL && i < n; i++) {
        PyObject *p = PySequence_Fast_GET_ITEM(cands, i);
        double x, y;
        if (item_double(p, 0, &x) < 0 || item_double(p, 1, &y) < 0) {
            Py_CLEAR(out);
            break;
        }
        double h = heading;
        double dt = step_time(s, x - px, y - py, &h), h_on = h;
        PyObject *entry = has_next ? Py_BuildValue("(Oddd)", p, dt, h, step_time(s, nx - x, ny - y, &h_on))
                                   : Py_BuildValue("(OddO)", p, dt, h, Py_None);
        if (entry == NULL) {
            Py_CLEAR(out);
            break;
        }
        PyTuple_SET_ITEM(out, i, entry);
    }
    Py_DECREF(cands);
    return out;
}

/* quickest(scored, t, cap, leg, rows, load): planners.collect.path.quickest, the scored candidate
 * the carrier leaves soonest from (the first of equals) and max(t + hop, ready) there */
static PyObject *
quickest(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double t, cap, load;
    if (nargs != 6 || Py_TYPE(args[3]) != &LegType) {
        PyErr_SetString(PyExc_TypeError, "quickest(scored, t, cap, leg: Leg, rows, load)");
        return NULL;
    }
    if (as_double(args[1], &t) < 0 || as_double(args[2], &cap) < 0 || as_double(args[5], &load) < 0)
        return NULL;
    PyObject *scored = PySequence_Fast(args[0], "scored must be a sequence");
    if (scored == NULL)
        return NULL;
    PyObject *best = NULL;
    double best_eta = INFINITY, best_max = INFINITY;
    for (Py_ssize_t i = 0; i < PySequence_Fast_GET_SIZE(scored); i++) {
        PyObject *entry = PySequence_Fast_GET_ITEM(scored, i);
        double hop, on = 0.0, x, y;
        if (!PyTuple_Check(entry) || PyTuple_GET_SIZE(entry) != 4) {
            PyErr_SetString(PyExc_TypeError, "scored entries are (stop, hop, heading, hop on)");
            goto fail;
        }
        PyObject *p = PyTuple_GET_ITEM(entry, 0), *on_obj = PyTuple_GET_ITEM(entry, 3);
        if (as_double(PyTuple_GET_ITEM(entry, 1), &hop) < 0 || (on_obj != Py_None && as_double(on_obj, &on) < 0))
            goto fail;
        double arrive = t + hop, held;
        if (arrive >= cap)
            held = arrive;
        else {
            double far;
            if (item_double(p, 0, &x) < 0 || item_double(p, 1, &y) < 0 || farthest_of(args[4], x, y, &far) < 0)
                goto fail;
            double ready = leg_time((LegObject *)args[3], far);
            held = ready > arrive ? ready : arrive;
        }
        double eta = held + load;
        if (on_obj != Py_None)
            eta += on;
        if (best == NULL || eta < best_eta)
            best = entry, best_eta = eta, best_max = held;
    }
    Py_DECREF(scored);
    if (best == NULL) {
        PyErr_SetString(PyExc_ValueError, "quickest of no candidates");
        return NULL;
    }
    return Py_BuildValue("(Od)", best, best_max);
fail:
    Py_DECREF(scored);
    return NULL;
}

/* route_times(hop, ready, load): planners.collect.path.route_times, eq. 5.2's departures (eta), the
 * hops and loads still to come after each stop (after) and the latest a later cluster's rovers
 * hold the carrier up (late, ending with -inf): prefix sums and running maxima */
static PyObject *
route_times(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double load;
    if (nargs != 3 || as_double(args[2], &load) < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "route_times(hop, ready, load)");
        return NULL;
    }
    PyObject *hop = PySequence_Fast(args[0], "hop must be a sequence");
    PyObject *ready = hop ? PySequence_Fast(args[1], "ready must be a sequence") : NULL;
    PyObject *eta = NULL, *after = NULL, *late = NULL, *out = NULL;
    double *total = NULL, *w = NULL;
    if (ready == NULL)
        goto done;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(hop);
    if (n == 0 || PySequence_Fast_GET_SIZE(ready) != n) {
        PyErr_SetString(PyExc_ValueError, "route_times: as many hops as ready times, at least one");
        goto done;
    }
    total = PyMem_Malloc((size_t)n * sizeof(double));
    w = PyMem_Malloc((size_t)n * sizeof(double));
    eta = PyList_New(n), after = PyList_New(n), late = PyList_New(n);
    if (total == NULL || w == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    if (eta == NULL || after == NULL || late == NULL)
        goto done;
    double sum = 0.0, top = 0.0;
    for (Py_ssize_t j = 0; j < n; j++) {
        double h, r;
        if (as_double(PySequence_Fast_GET_ITEM(hop, j), &h) < 0 || as_double(PySequence_Fast_GET_ITEM(ready, j), &r) < 0)
            goto done;
        sum = j ? sum + (h + load) : h + load;
        total[j] = sum;
        w[j] = r + load - sum;
        if (j == 0 || w[j] > top)  /* the running maximum of w */
            top = w[j];
        PyObject *e = PyFloat_FromDouble(sum + (top > 0.0 ? top : 0.0));
        if (e == NULL)
            goto done;
        PyList_SET_ITEM(eta, j, e);
    }
    double end = total[n - 1], back = -INFINITY;
    for (Py_ssize_t j = n - 1; j >= 0; j--) {
        PyObject *a = PyFloat_FromDouble(end - total[j]);
        PyObject *l = PyFloat_FromDouble(j == n - 1 ? -INFINITY : end + back);
        if (a == NULL || l == NULL) {
            Py_XDECREF(a);
            Py_XDECREF(l);
            goto done;
        }
        PyList_SET_ITEM(after, j, a);
        PyList_SET_ITEM(late, j, l);
        if (j == n - 1 || w[j] > back)  /* the running maximum of w from the end */
            back = w[j];
    }
    out = PyTuple_Pack(3, eta, after, late);
done:
    PyMem_Free(total);
    PyMem_Free(w);
    Py_XDECREF(eta);
    Py_XDECREF(after);
    Py_XDECREF(late);
    Py_XDECREF(ready);
    Py_XDECREF(hop);
    return out;
}

/* deploy_times(hop, fly, unload): planners.deploy.path.deploy_times, per stop the carrier's arrival,
 * when its rovers are done, and the running maxima of done from the end (tail) and the start
 * (head) */
static PyObject *
deploy_times(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double unload;
    if (nargs != 3 || as_double(args[2], &unload) < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "deploy_times(hop, fly, unload)");
        return NULL;
    }
    PyObject *hop = PySequence_Fast(args[0], "hop must be a sequence");
    PyObject *fly = hop ? PySequence_Fast(args[1], "fly must be a sequence") : NULL;
    PyObject *lists[4] = {NULL, NULL, NULL, NULL}, *out = NULL;  /* arrive, done, tail, head */
    double *done = NULL;
    if (fly == NULL)
        goto end;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(hop);
    if (PySequence_Fast_GET_SIZE(fly) != n) {
        PyErr_SetString(PyExc_ValueError, "deploy_times: as many hops as flights");
        goto end;
    }
    done = PyMem_Malloc((size_t)(n + 1) * sizeof(double));
    if (done == NULL) {
        PyErr_NoMemory();
        goto end;
    }
    for (int q = 0; q < 4; q++)
        if ((lists[q] = PyList_New(n)) == NULL)
            goto end;
    double depart = 0.0, head = 0.0;
    for (Py_ssize_t j = 0; j < n; j++) {
        double h, f;
        if (as_double(PySequence_Fast_GET_ITEM(hop, j), &h) < 0 || as_double(PySequence_Fast_GET_ITEM(fly, j), &f) < 0)
            goto end;
        depart = j ? depart + (h + unload) : h + unload;
        done[j] = depart + f;
        if (j == 0 || done[j] > head)
            head = done[j];
        PyObject *a = PyFloat_FromDouble(depart - unload), *d = PyFloat_FromDouble(done[j]);
        PyObject *hd = PyFloat_FromDouble(head);
        if (a == NULL || d == NULL || hd == NULL) {
            Py_XDECREF(a);
            Py_XDECREF(d);
            Py_XDECREF(hd);
            goto end;
        }
        PyList_SET_ITEM(lists[0], j, a);
        PyList_SET_ITEM(lists[1], j, d);
        PyList_SET_ITEM(lists[3], j, hd);
    }
    double tail = 0.0;
    for (Py_ssize_t j = n - 1; j >= 0; j--) {
        if (j == n - 1 || done[j] > tail)
            tail = done[j];
        PyObject *t = PyFloat_FromDouble(tail);
        if (t == NULL)
            goto end;
        PyList_SET_ITEM(lists[2], j, t);
    }
    out = PyTuple_Pack(4, lists[0], lists[1], lists[2], lists[3]);
end:
    PyMem_Free(done);
    for (int q = 0; q < 4; q++)
        Py_XDECREF(lists[q]);
    Py_XDECREF(fly);
    Py_XDECREF(hop);
    return out;
}

/* ---- one stop moved, the others kept: the polishes' cost of a stop at (x, y) ---- */

static int
rows_of(PyObject *seq_obj, int width, double **out, Py_ssize_t *count)
{
    PyObject *seq = PySequence_Fast(seq_obj, "rows must be a sequence");
    if (seq == NULL)
        return -1;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(seq);
    *out = PyMem_Malloc((size_t)(n * width + 1) * sizeof(double));
    *count = n;
    if (*out == NULL) {
        Py_DECREF(seq);
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t i = 0; i < n; i++)
        for (int c = 0; c < width; c++)
            if (item_double(PySequence_Fast_GET_ITEM(seq, i), c, &(*out)[i * width + c]) < 0) {
                Py_DECREF(seq);
                return -1;
            }
    Py_DECREF(seq);
    return 0;
}

/* a tuple of numbers, or None (has = 0) */
static int
numbers_of(PyObject *t, int count, double *out, int *has)
{
    *has = t != Py_None;
    for (int c = 0; *has && c < count; c++)
        if (item_double(t, c, &out[c]) < 0)
            return -1;
    return 0;
}

static int
time_models(PyObject *step, PyObject *leg, StepperObject **s, LegObject **l)
{
    if (Py_TYPE(step) != &StepperType || Py_TYPE(leg) != &LegType) {
        PyErr_SetString(PyExc_TypeError, "step and leg must be the compiled Stepper and Leg");
        return -1;
    }
    *s = (StepperObject *)Py_NewRef(step);
    *l = (LegObject *)Py_NewRef(leg);
    return 0;
}

static int
xy_args(PyObject *const *args, size_t nargsf, PyObject *kwnames, double *x, double *y)
{
    if (PyVectorcall_NARGS(nargsf) != 2 || (kwnames && PyTuple_GET_SIZE(kwnames))) {
        PyErr_SetString(PyExc_TypeError, "cost(x, y)");
        return -1;
    }
    return (as_double(args[0], x) < 0 || as_double(args[1], y) < 0) ? -1 : 0;
}

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    StepperObject *step;
    LegObject *leg;
    double *rows;  /* x, y, z² of the stop's tasks */
    Py_ssize_t nrows;
    double d2max, start[4], unload, head, next1[4], next2[4], w;
    int has1, has2, has_h12, has_w;
} DeployCostObject;

/* planners.deploy.stops.deploy_stop_cost's cost(x, y) */
static PyObject *
deploy_cost_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    DeployCostObject *c = (DeployCostObject *)self;
    double x, y;
    if (xy_args(args, nargsf, kwnames, &x, &y) < 0)
        return NULL;
    double far = 0.0;
    for (Py_ssize_t i = 0; i < c->nrows; i++) {
        const double *r = c->rows + 3 * i;
        double e = py_square(r[0] - x) + py_square(r[1] - y) + r[2];
        if (e > far)
            far = e;
    }
    if (far > c->d2max)
        return PyFloat_FromDouble(INFINITY);
    double h = c->start[2];
    double dt = step_time(c->step, x - c->start[0], y - c->start[1], &h);
    double t = c->start[3] + dt + c->unload;
    double worst = c->head;
    double v = t + leg_time(c->leg, sqrt(far));
    if (v > worst)
        worst = v;
    if (c->has1) {
        dt = step_time(c->step, c->next1[0] - x, c->next1[1] - y, &h);
        double t1 = t + dt;
        v = c->next1[2] + (t1 - c->next1[3]);
        if (v > worst)
            worst = v;
        if (c->has2) {
            dt = c->next2[0];
            if (c->has_h12 && c->has_w) {
                double turn = py_mod_tau(c->next2[1] - h);
                dt += (!(TAU - turn < turn) ? turn : TAU - turn) / c->w;
            }
            else if (!c->has_h12)
                dt = 0.0;
            v = c->next2[2] + (t1 + c->unload + dt - c->next2[3]);
            if (v > worst)
                worst = v;
        }
    }
    return PyFloat_FromDouble(worst);
}

static PyObject *
deploy_cost_new(PyTypeObject *type, PyObject *args, PyObject *kw)
{
    PyObject *rows, *step, *leg, *start, *next1, *next2, *w;
    double d2max, unload, head;
    if (!PyArg_ParseTuple(args, "OdOOOddOOO:DeployStopCost", &rows, &d2max, &step, &leg, &start, &unload,
                          &head, &next1, &next2, &w))
        return NULL;
    DeployCostObject *c = (DeployCostObject *)type->tp_alloc(type, 0);
    if (c == NULL)
        return NULL;
    c->vectorcall = deploy_cost_call;
    c->d2max = d2max, c->unload = unload, c->head = head;
    int has_start;
    PyObject *h12 = NULL;
    if (time_models(step, leg, &c->step, &c->leg) < 0 || rows_of(rows, 3, &c->rows, &c->nrows) < 0
        || numbers_of(start, 4, c->start, &has_start) < 0 || numbers_of(next1, 4, c->next1, &c->has1) < 0
        || ((c->has_w = w != Py_None) && as_double(w, &c->w) < 0))
        goto fail;
    c->has2 = c->has1 && next2 != Py_None;
    if (c->has2) {  /* (hop12, h12 or None, tail2, arrive2) */
        h12 = PySequence_GetItem(next2, 1);
        if (h12 == NULL || item_double(next2, 0, &c->next2[0]) < 0 || item_double(next2, 2, &c->next2[2]) < 0
            || item_double(next2, 3, &c->next2[3]) < 0
            || ((c->has_h12 = h12 != Py_None) && as_double(h12, &c->next2[1]) < 0))
            goto fail;
        Py_CLEAR(h12);
    }
    if (!has_start) {
        PyErr_SetString(PyExc_TypeError, "start: (x, y, heading, time)");
        goto fail;
    }
    return (PyObject *)c;
fail:
    Py_XDECREF(h12);
    Py_DECREF(c);
    return NULL;
}

typedef struct {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    StepperObject *step;
    LegObject *leg;
    double *rows;   /* x, y, ρ², z² of the stop's rovers */
    double *later;  /* x, y, ready of the next stops */
    Py_ssize_t nrows, nlater;
    double start[4], load, tail[2];
    int has_tail;
} CollectCostObject;

/* planners.collect.polish.collect_stop_cost's cost(x, y) */
static PyObject *
collect_cost_call(PyObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    CollectCostObject *c = (CollectCostObject *)self;
    double x, y;
    if (xy_args(args, nargsf, kwnames, &x, &y) < 0)
        return NULL;
    double far = 0.0;
    for (Py_ssize_t i = 0; i < c->nrows; i++) {
        const double *r = c->rows + 4 * i;
        double e = py_square(x - r[0]) + py_square(y - r[1]);
        if (e > r[2])
            return PyFloat_FromDouble(INFINITY);
        if (e + r[3] > far)
            far = e + r[3];
    }
    double h = c->start[2];
    double dt = step_time(c->step, x - c->start[0], y - c->start[1], &h);
    double t = c->start[3] + dt, ready = leg_time(c->leg, sqrt(far));
    t = (ready > t ? ready : t) + c->load;
    double qx = x, qy = y;
    for (Py_ssize_t j = 0; j < c->nlater; j++) {
        const double *q = c->later + 3 * j;
        t += step_time(c->step, q[0] - qx, q[1] - qy, &h);
        if (q[2] > t)
            t = q[2];
        t += c->load;
        qx = q[0], qy = q[1];
    }
    if (c->has_tail) {
        t += c->tail[0];
        return PyFloat_FromDouble(c->tail[1] > t ? c->tail[1] : t);
    }
    return PyFloat_FromDouble(t);
}

static PyObject *
collect_cost_new(PyTypeObject *type, PyObject *args, PyObject *kw)
{
    PyObject *rows, *step, *leg, *start, *later, *tail;
    double load;
    if (!PyArg_ParseTuple(args, "OOOOdOO:CollectStopCost", &rows, &step, &leg, &start, &load, &later, &tail))
        return NULL;
    CollectCostObject *c = (CollectCostObject *)type->tp_alloc(type, 0);
    if (c == NULL)
        return NULL;
    c->vectorcall = collect_cost_call;
    c->load = load;
    int has_start;
    if (time_models(step, leg, &c->step, &c->leg) < 0 || rows_of(rows, 4, &c->rows, &c->nrows) < 0
        || rows_of(later, 3, &c->later, &c->nlater) < 0 || numbers_of(start, 4, c->start, &has_start) < 0
        || numbers_of(tail, 2, c->tail, &c->has_tail) < 0) {
        Py_DECREF(c);
        return NULL;
    }
    if (!has_start) {
        PyErr_SetString(PyExc_TypeError, "start: (x, y, heading, time)");
        Py_DECREF(c);
        return NULL;
    }
    return (PyObject *)c;
}

static void
deploy_cost_dealloc(DeployCostObject *c)
{
    PyMem_Free(c->rows);
    Py_XDECREF(c->step);
    Py_XDECREF(c->leg);
    Py_TYPE(c)->tp_free((PyObject *)c);
}

static void
collect_cost_dealloc(CollectCostObject *c)
{
    PyMem_Free(c->rows);
    PyMem_Free(c->later);
    Py_XDECREF(c->step);
    Py_XDECREF(c->leg);
    Py_TYPE(c)->tp_free((PyObject *)c);
}

static PyTypeObject DeployCostType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.DeployStopCost",
    .tp_basicsize = sizeof(DeployCostObject),
    .tp_dealloc = (destructor)deploy_cost_dealloc,
    .tp_vectorcall_offset = offsetof(DeployCostObject, vectorcall),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_doc = "planners.deploy.stops.deploy_stop_cost (the same floats)",
    .tp_call = PyVectorcall_Call,
    .tp_new = deploy_cost_new,
};

static PyTypeObject CollectCostType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.CollectStopCost",
    .tp_basicsize = sizeof(CollectCostObject),
    .tp_dealloc = (destructor)collect_cost_dealloc,
    .tp_vectorcall_offset = offsetof(CollectCostObject, vectorcall),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_doc = "planners.collect.polish.collect_stop_cost (the same floats)",
    .tp_call = PyVectorcall_Call,
    .tp_new = collect_cost_new,
};

/* ---- planners.core.geometry.EnclosingCircles: power-weighted enclosing circles of subsets of one
 * set of points, remembered by membership and derived from a neighbouring subset's support ---- */

#define REL_EPS 1e-9  /* planners.core.geometry._REL_EPS */

typedef struct { double x, y, r; } Circ;

/* one subset's points in Welzl's visiting order, and the Python function a degenerate closed form
 * falls back to (geometry._boundary_circle) */
typedef struct {
    const double *x, *y, *w;
    PyObject *fallback;
} Pts;

static int
boundary_circle(const Pts *p, const Py_ssize_t *idx, int k, Circ *out)
{
    PyObject *pts = PyList_New(k), *ws = PyList_New(k), *res = NULL;
    int rc = -1;
    if (pts == NULL || ws == NULL)
        goto done;
    for (int t = 0; t < k; t++) {
        PyObject *pt = point(p->x[idx[t]], p->y[idx[t]]);
        PyObject *w = PyFloat_FromDouble(p->w[idx[t]]);
        if (pt == NULL || w == NULL) {
            Py_XDECREF(pt);
            Py_XDECREF(w);
            goto done;
        }
        PyList_SET_ITEM(pts, t, pt);
        PyList_SET_ITEM(ws, t, w);
    }
    res = PyObject_CallFunctionObjArgs(p->fallback, pts, ws, NULL);
    if (res != NULL && triple(res, &out->x, &out->y, &out->r) == 0)
        rc = 0;
done:
    Py_XDECREF(pts);
    Py_XDECREF(ws);
    Py_XDECREF(res);
    return rc;
}

/* geometry._one */
static inline Circ
circle_one(const Pts *p, Py_ssize_t i)
{
    double w = p->w[i];
    return (Circ){p->x[i], p->y[i], sqrt(0.0 > w ? 0.0 : w)};
}

/* geometry._two */
static int
circle_two(const Pts *p, Py_ssize_t i, Py_ssize_t j, Circ *out)
{
    double x0 = p->x[i], y0 = p->y[i], w0 = p->w[i];
    double x1 = p->x[j], y1 = p->y[j], w1 = p->w[j];
    double ux = x1 - x0, uy = y1 - y0;
    double n = ux * ux + uy * uy;
    if (n < 1e-24) {
        Py_ssize_t idx[2] = {i, j};
        return boundary_circle(p, idx, 2, out);
    }
    double lam = (n + w1 - w0) / (2.0 * n);
    double cx = x0 + lam * ux, cy = y0 + lam * uy;
    double value = py_square(py_hypot(cx - x0, cy - y0)) + w0;
    double v1 = py_square(py_hypot(cx - x1, cy - y1)) + w1;
    if (v1 > value)
        value = v1;
    *out = (Circ){cx, cy, sqrt(0.0 > value ? 0.0 : value)};
    return 0;
}

/* geometry._three */
static int
circle_three(const Pts *p, Py_ssize_t i, Py_ssize_t j, Py_ssize_t k, Circ *out)
{
    double x0 = p->x[i], y0 = p->y[i], w0 = p->w[i];
    double x1 = p->x[j], y1 = p->y[j], w1 = p->w[j];
    double x2 = p->x[k], y2 = p->y[k], w2 = p->w[k];
    double u1x = x1 - x0, u1y = y1 - y0;
    double u2x = x2 - x0, u2y = y2 - y0;
    double b1 = u1x * u1x + u1y * u1y + w1 - w0;
    double b2 = u2x * u2x + u2y * u2y + w2 - w0;
    double det = u1x * u2y - u1y * u2x;
    double size = (u1x * u1x + u1y * u1y) * (u2x * u2x + u2y * u2y);
    if (fabs(det) < 1e-12 * pow_fn(size > 1.0 ? size : 1.0, 0.5)) {
        Py_ssize_t idx[3] = {i, j, k};
        return boundary_circle(p, idx, 3, out);
    }
    double cx = x0 + (b1 * u2y - b2 * u1y) / (2.0 * det), cy = y0 + (u1x * b2 - u2x * b1) / (2.0 * det);
    double value = py_square(py_hypot(cx - x0, cy - y0)) + w0;
    double v1 = py_square(py_hypot(cx - x1, cy - y1)) + w1;
    if (v1 > value)
        value = v1;
    double v2 = py_square(py_hypot(cx - x2, cy - y2)) + w2;
    if (v2 > value)
        value = v2;
    *out = (Circ){cx, cy, sqrt(0.0 > value ? 0.0 : value)};
    return 0;
}

/* geometry._tolerance (builtins' max and min: the first of equals) */
static int
circle_tolerance(const Pts *p, Py_ssize_t m, double *eps)
{
    double hx = p->x[0], hy = p->y[0], lx = p->x[0], ly = p->y[0], hw = p->w[0];
    for (Py_ssize_t q = 1; q < m; q++) {
        if (p->x[q] > hx)
            hx = p->x[q];
        if (p->y[q] > hy)
            hy = p->y[q];
        if (p->x[q] < lx)
            lx = p->x[q];
        if (p->y[q] < ly)
            ly = p->y[q];
        if (p->w[q] > hw)
            hw = p->w[q];
    }
    if (hw < 0.0) {
        PyErr_SetString(PyExc_ValueError, "math domain error");
        return -1;
    }
    double vs[3] = {hy > hx ? hy : hx, -(ly < lx ? ly : lx), sqrt(hw)};
    double size = 1.0;
    for (int t = 0; t < 3; t++)
        if (vs[t] > size)
            size = vs[t];
    *eps = REL_EPS * size;
    return 0;
}

static inline double
power_of(const Pts *p, Circ c, Py_ssize_t i)
{
    return py_square(c.x - p->x[i]) + py_square(c.y - p->y[i]) + p->w[i];
}

typedef struct { Py_ssize_t q[3]; int n; } Support;  /* support points, in the order they were put on */

/* geometry._welzl_2d over the m points */
static int
welzl_2d(const Pts *p, Py_ssize_t m, Circ *out, Support *sup)
{
    double eps;
    if (circle_tolerance(p, m, &eps) < 0)
        return -1;
    Circ c = circle_one(p, 0);
    double lim = py_square(c.r + eps);
    *sup = (Support){{0, 0, 0}, 1};
    for (Py_ssize_t i = 1; i < m; i++) {
        if (power_of(p, c, i) <= lim)
            continue;
        c = circle_one(p, i);
        lim = py_square(c.r + eps);
        *sup = (Support){{i, 0, 0}, 1};
        for (Py_ssize_t j = 0; j < i; j++) {
            if (power_of(p, c, j) <= lim)
                continue;
            if (circle_two(p, i, j, &c) < 0)
                return -1;
            lim = py_square(c.r + eps);
            *sup = (Support){{i, j, 0}, 2};
            for (Py_ssize_t k = 0; k < j; k++) {
                if (power_of(p, c, k) > lim) {
                    if (circle_three(p, i, j, k, &c) < 0)
                        return -1;
                    lim = py_square(c.r + eps);
                    *sup = (Support){{i, j, k}, 3};
                }
            }
        }
    }
    *out = c;
    return 0;
}

/* geometry._welzl_through: point a on the boundary, the points `first` visited first; rest: room
 * for m + 3 indices */
static int
welzl_through(const Pts *p, Py_ssize_t m, Py_ssize_t a, const Support *first, Py_ssize_t *rest,
              Support *sup)
{
    double eps;
    if (circle_tolerance(p, m, &eps) < 0)
        return -1;
    Py_ssize_t len = 0;
    for (int t = 0; t < first->n; t++)
        rest[len++] = first->q[t];
    for (Py_ssize_t q = 0; q < m; q++) {
        int in_first = 0;
        for (int t = 0; t < first->n; t++)
            in_first |= first->q[t] == q;
        if (q != a && !in_first)
            rest[len++] = q;
    }
    Circ c = circle_one(p, a);
    *sup = (Support){{a, 0, 0}, 1};
    for (Py_ssize_t jj = 0; jj < len; jj++) {
        Py_ssize_t j = rest[jj];
        if (power_of(p, c, j) <= py_square(c.r + eps))
            continue;
        if (circle_two(p, a, j, &c) < 0)
            return -1;
        *sup = (Support){{a, j, 0}, 2};
        for (Py_ssize_t kk = 0; kk < jj; kk++) {
            Py_ssize_t k = rest[kk];
            if (power_of(p, c, k) > py_square(c.r + eps)) {
                if (circle_three(p, a, j, k, &c) < 0)
                    return -1;
                *sup = (Support){{a, j, k}, 3};
            }
        }
    }
    return 0;
}

/* geometry._on_support: the closed form on the support points, latest visited first */
static int
on_support(const Pts *p, const Support *sup, Circ *out)
{
    Py_ssize_t s[3] = {sup->q[0], sup->q[1], sup->q[2]};
    for (int a = 1; a < sup->n; a++)  /* sorted(sup, reverse=True) */
        for (int b = a; b > 0 && s[b] > s[b - 1]; b--) {
            Py_ssize_t t = s[b];
            s[b] = s[b - 1];
            s[b - 1] = t;
        }
    if (sup->n == 1) {
        *out = circle_one(p, s[0]);
        return 0;
    }
    if (sup->n == 2)
        return circle_two(p, s[0], s[1], out);
    return circle_three(p, s[0], s[1], s[2], out);
}

typedef struct {
    PyObject_HEAD
    Py_ssize_t n;
    double *x, *y;
    PyObject *known;     /* sorted membership -> (circle, support) */
    PyObject *fallback;  /* geometry._boundary_circle */
    PyObject *shuffled;  /* geometry._shuffled: Welzl's visiting order */
} CirclesObject;

/* one subset being solved: its members, visiting order and the inverse, points in that order */
typedef struct {
    Py_ssize_t m;
    Py_ssize_t *kv, *order, *rank, *rest;
    Pts pts;
} Subset;

static Py_ssize_t
position_in(const Py_ssize_t *vals, Py_ssize_t len, Py_ssize_t g)
{
    for (Py_ssize_t q = 0; q < len; q++)
        if (vals[q] == g)
            return q;
    return -1;
}

static PyObject *
support_tuple(PyObject *key, const Subset *s, const Support *sup)
{
    PyObject *t = PyTuple_New(sup->n);
    if (t == NULL)
        return NULL;
    for (int q = 0; q < sup->n; q++)
        PyTuple_SET_ITEM(t, q, Py_NewRef(PyTuple_GET_ITEM(key, s->order[sup->q[q]])));
    return t;
}

/* how a neighbour's entry relates to the subset: the visiting positions of its support (local),
 * and the added member's (or -1 when none was added); 0 when it cannot give the circle */
static int
neighbour_support(PyObject *other, PyObject *entry, const Subset *s, Support *local, Py_ssize_t *added_at)
{
    if (!PyTuple_Check(other)) {
        PyErr_SetString(PyExc_TypeError, "near: memberships must be tuples");
        return -1;
    }
    Py_ssize_t lo = PyTuple_GET_SIZE(other), added = 0, at = -1;
    Py_ssize_t ov[lo > 0 ? lo : 1];
    for (Py_ssize_t q = 0; q < lo; q++)
        if ((ov[q] = PyLong_AsSsize_t(PyTuple_GET_ITEM(other, q))) == -1 && PyErr_Occurred())
            return -1;
    for (Py_ssize_t q = 0; q < s->m && added <= 1; q++)
        if (position_in(ov, lo, s->kv[q]) < 0) {
            added++;
            at = q;
        }
    if (added > 1 || lo - s->m + added > 1)
        return 0;
    PyObject *support = PyTuple_GET_ITEM(entry, 1);
    local->n = (int)PyTuple_GET_SIZE(support);
    for (int t = 0; t < local->n; t++) {
        Py_ssize_t g = PyLong_AsSsize_t(PyTuple_GET_ITEM(support, t));
        Py_ssize_t q = position_in(s->kv, s->m, g);
        if (q < 0)
            return 0;  /* a support point was removed */
        local->q[t] = s->rank[q];
    }
    *added_at = added ? s->rank[at] : -1;
    return 1;
}

/* EnclosingCircles._derive: 1 with the circle and its support (a new reference), 0 when no
 * neighbour gives it, -1 on error */
static int
derive(CirclesObject *self, PyObject *key, const Subset *s, PyObject *near, Circ *out, PyObject **support)
{
    PyObject *seq = PySequence_Fast(near, "near: a sequence of memberships");
    if (seq == NULL)
        return -1;
    Py_ssize_t out_a = -1;
    Support out_local = {{0, 0, 0}, 0};
    int rc = 0;
    for (Py_ssize_t t = 0; t < PySequence_Fast_GET_SIZE(seq) && rc == 0; t++) {
        PyObject *other = PySequence_Fast_GET_ITEM(seq, t);
        Py_ssize_t lo = PyObject_Length(other);
        if (lo < 0) {
            rc = -1;
            break;
        }
        if (s->m - lo < -1 || s->m - lo > 1)
            continue;
        PyObject *entry = PyDict_GetItemWithError(self->known, other);
        if (entry == NULL) {
            rc = PyErr_Occurred() ? -1 : 0;
            continue;
        }
        Support local;
        Py_ssize_t a;
        int ok = neighbour_support(other, entry, s, &local, &a);
        if (ok <= 0) {
            rc = ok;
            continue;
        }
        Circ c;
        if (on_support(&s->pts, &local, &c) < 0) {
            rc = -1;
            break;
        }
        if (a < 0) {
            *out = c;
            *support = Py_NewRef(PyTuple_GET_ITEM(entry, 1));
            rc = 1;
            break;
        }
        double margin = 2.0 * REL_EPS * (1.0 + fabs(c.x) + fabs(c.y) + c.r);
        double power = power_of(&s->pts, c, a);
        if (c.r > margin && power < py_square(c.r - margin)) {
            *out = c;
            *support = Py_NewRef(PyTuple_GET_ITEM(entry, 1));
            rc = 1;
            break;
        }
        if (out_a < 0 && power > py_square(c.r + margin)) {
            out_a = a;
            out_local = local;
        }
    }
    Py_DECREF(seq);
    if (rc != 0 || out_a < 0)
        return rc;
    Support sup;
    if (welzl_through(&s->pts, s->m, out_a, &out_local, s->rest, &sup) < 0 || on_support(&s->pts, &sup, out) < 0)
        return -1;
    *support = support_tuple(key, s, &sup);
    return *support == NULL ? -1 : 1;
}

/* reads the subset `key` (weights: one per member or None) in Welzl's visiting order */
static int
subset_read(CirclesObject *self, PyObject *key, PyObject *weights, Subset *s, void **mem)
{
    Py_ssize_t m = PyTuple_GET_SIZE(key);
    PyObject *order = PyObject_CallFunction(self->shuffled, "ni", m, 0);
    if (order == NULL)
        return -1;
    PyObject *fast = PySequence_Fast(order, "visiting order");
    Py_DECREF(order);
    if (fast == NULL)
        return -1;
    *mem = PyMem_Malloc((size_t)(m + 1) * (4 * sizeof(Py_ssize_t) + 3 * sizeof(double)) + 3 * sizeof(Py_ssize_t));
    if (*mem == NULL) {
        Py_DECREF(fast);
        PyErr_NoMemory();
        return -1;
    }
    double *d = *mem;
    Py_ssize_t *z = (Py_ssize_t *)(d + 3 * (m + 1));
    s->m = m;
    s->pts = (Pts){d, d + (m + 1), d + 2 * (m + 1), self->fallback};
    s->kv = z, s->order = z + (m + 1), s->rank = z + 2 * (m + 1), s->rest = z + 3 * (m + 1);
    double *x = d, *y = d + (m + 1), *w = d + 2 * (m + 1);
    int rc = 0;
    for (Py_ssize_t q = 0; q < m && rc == 0; q++) {
        Py_ssize_t g = PyLong_AsSsize_t(PyTuple_GET_ITEM(key, q));
        Py_ssize_t o = PyLong_AsSsize_t(PySequence_Fast_GET_ITEM(fast, q));
        if (PyErr_Occurred())
            rc = -1;
        else if (g < 0 || g >= self->n || o < 0 || o >= m) {
            PyErr_SetString(PyExc_IndexError, "point index out of range");
            rc = -1;
        } else {
            s->kv[q] = g;
            s->order[q] = o;
        }
    }
    Py_DECREF(fast);
    for (Py_ssize_t q = 0; q < m && rc == 0; q++) {
        Py_ssize_t o = s->order[q], g = s->kv[o];
        s->rank[o] = q;
        x[q] = self->x[g];
        y[q] = self->y[g];
        w[q] = 0.0;
        if (weights != Py_None && item_double(weights, o, &w[q]) < 0)
            rc = -1;
    }
    return rc;
}

/* Circles.get(key, weights=None, near=()): EnclosingCircles.get */
static PyObject *
circles_get(CirclesObject *self, PyObject *const *args, size_t nargsf, PyObject *kwnames)
{
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    PyObject *given[3] = {NULL, Py_None, NULL};
    static const char *names[3] = {"key", "weights", "near"};
    if (nargs > 3)
        goto usage;
    for (Py_ssize_t t = 0; t < nargs; t++)
        given[t] = args[t];
    for (Py_ssize_t t = 0; kwnames != NULL && t < PyTuple_GET_SIZE(kwnames); t++) {
        int slot = -1;
        for (int q = 0; q < 3; q++)
            if (PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, t), names[q]) == 0)
                slot = q;
        if (slot < nargs)
            goto usage;
        given[slot] = args[nargs + t];
    }
    PyObject *key = given[0], *weights = given[1], *near = given[2];
    if (key == NULL || !PyTuple_Check(key))
        goto usage;
    PyObject *got = PyDict_GetItemWithError(self->known, key);
    if (got != NULL)
        return Py_NewRef(PyTuple_GET_ITEM(got, 0));
    if (PyErr_Occurred())
        return NULL;
    if (PyTuple_GET_SIZE(key) == 0) {
        PyErr_SetString(PyExc_ValueError, "the enclosing circle of no points");
        return NULL;
    }
    Subset s;
    void *mem = NULL;
    PyObject *support = NULL, *circle = NULL, *entry = NULL;
    Circ c;
    int found = 0;
    if (subset_read(self, key, weights, &s, &mem) < 0)
        goto done;
    if (near != NULL && s.m > 1) {
        int has = PyObject_IsTrue(near);
        if (has < 0 || (has && (found = derive(self, key, &s, near, &c, &support)) < 0))
            goto done;
    }
    if (!found) {
        Support sup;
        if (welzl_2d(&s.pts, s.m, &c, &sup) < 0 || (support = support_tuple(key, &s, &sup)) == NULL)
            goto done;
    }
    circle = Py_BuildValue("(ddd)", c.x, c.y, c.r);
    entry = circle ? PyTuple_Pack(2, circle, support) : NULL;
    if (entry == NULL || PyDict_SetItem(self->known, key, entry) < 0)
        Py_CLEAR(circle);
done:
    PyMem_Free(mem);
    Py_XDECREF(support);
    Py_XDECREF(entry);
    return circle;
usage:
    PyErr_SetString(PyExc_TypeError, "get(key: tuple, weights=None, near=())");
    return NULL;
}

static PyObject *
circles_new(PyTypeObject *type, PyObject *args, PyObject *kw)
{
    PyObject *points, *fallback, *shuffled;
    if (!PyArg_ParseTuple(args, "OOO:Circles", &points, &fallback, &shuffled))
        return NULL;
    PyObject *fast = PySequence_Fast(points, "points must be a sequence");
    if (fast == NULL)
        return NULL;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(fast);
    CirclesObject *self = (CirclesObject *)type->tp_alloc(type, 0);
    if (self == NULL) {
        Py_DECREF(fast);
        return NULL;
    }
    self->x = PyMem_Malloc((size_t)(n + 1) * sizeof(double));
    self->y = PyMem_Malloc((size_t)(n + 1) * sizeof(double));
    self->known = PyDict_New();
    self->fallback = Py_NewRef(fallback);
    self->shuffled = Py_NewRef(shuffled);
    self->n = n;
    if (self->x == NULL || self->y == NULL || self->known == NULL) {
        Py_DECREF(fast);
        Py_DECREF(self);
        return PyErr_Occurred() ? NULL : PyErr_NoMemory();
    }
    for (Py_ssize_t i = 0; i < n; i++)
        if (item_double(PySequence_Fast_GET_ITEM(fast, i), 0, &self->x[i]) < 0
            || item_double(PySequence_Fast_GET_ITEM(fast, i), 1, &self->y[i]) < 0) {
            Py_DECREF(fast);
            Py_DECREF(self);
            return NULL;
        }
    Py_DECREF(fast);
    return (PyObject *)self;
}

static void
circles_dealloc(CirclesObject *self)
{
    PyMem_Free(self->x);
    PyMem_Free(self->y);
    Py_XDECREF(self->known);
    Py_XDECREF(self->fallback);
    Py_XDECREF(self->shuffled);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyMethodDef circles_methods[] = {
    {"get", (PyCFunction)(void (*)(void))circles_get, METH_FASTCALL | METH_KEYWORDS,
     "EnclosingCircles.get: the circle (x, y, radius) of the points `key`, the same floats."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject CirclesType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Circles",
    .tp_basicsize = sizeof(CirclesObject),
    .tp_dealloc = (destructor)circles_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Circles(points, fallback, shuffled): planners.core.geometry.EnclosingCircles.",
    .tp_methods = circles_methods,
    .tp_new = circles_new,
};

/* welzl_2d(xs, ys, ws, fallback): planners.core.geometry._welzl_2d over points already in their
 * visiting order, ((x, y, radius), support) */
static PyObject *
welzl_2d_(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 4) {
        PyErr_SetString(PyExc_TypeError, "welzl_2d(xs, ys, ws, fallback)");
        return NULL;
    }
    Py_ssize_t m = PyObject_Length(args[0]);
    if (m < 0)
        return NULL;
    if (m == 0 || PyObject_Length(args[1]) != m || PyObject_Length(args[2]) != m) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "welzl_2d: as many xs, ys and ws, at least one");
        return NULL;
    }
    double *d = PyMem_Malloc((size_t)(3 * m) * sizeof(double));
    if (d == NULL)
        return PyErr_NoMemory();
    for (Py_ssize_t q = 0; q < m; q++)
        if (item_double(args[0], q, &d[q]) < 0 || item_double(args[1], q, &d[m + q]) < 0
            || item_double(args[2], q, &d[2 * m + q]) < 0) {
            PyMem_Free(d);
            return NULL;
        }
    Pts p = {d, d + m, d + 2 * m, args[3]};
    Circ c;
    Support sup;
    PyObject *out = NULL;
    if (welzl_2d(&p, m, &c, &sup) == 0) {
        if (sup.n == 1)
            out = Py_BuildValue("((ddd)(n))", c.x, c.y, c.r, sup.q[0]);
        else if (sup.n == 2)
            out = Py_BuildValue("((ddd)(nn))", c.x, c.y, c.r, sup.q[0], sup.q[1]);
        else
            out = Py_BuildValue("((ddd)(nnn))", c.x, c.y, c.r, sup.q[0], sup.q[1], sup.q[2]);
    }
    PyMem_Free(d);
    return out;
}

/* reach_of(rows, members, x, y): planners.deploy.cluster.reach_of, the longest flight from (x, y)
 * on the ground to the members' rows (x, y, z²) */
static PyObject *
reach_of(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double x, y;
    if (nargs != 4 || as_double(args[2], &x) < 0 || as_double(args[3], &y) < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_TypeError, "reach_of(rows, members, x, y)");
        return NULL;
    }
    PyObject *rows = PySequence_Fast(args[0], "rows must be a sequence");
    if (rows == NULL)
        return NULL;
    PyObject *members = PySequence_Fast(args[1], "members must be a sequence");
    if (members == NULL) {
        Py_DECREF(rows);
        return NULL;
    }
    Py_ssize_t n = PySequence_Fast_GET_SIZE(rows);
    double worst = 0.0;
    int rc = 0;
    for (Py_ssize_t t = 0; t < PySequence_Fast_GET_SIZE(members) && rc == 0; t++) {
        Py_ssize_t i = PyNumber_AsSsize_t(PySequence_Fast_GET_ITEM(members, t), PyExc_IndexError);
        if (i == -1 && PyErr_Occurred()) {
            rc = -1;
            break;
        }
        if (i < 0)
            i += n;
        if (i < 0 || i >= n) {
            PyErr_SetString(PyExc_IndexError, "list index out of range");
            rc = -1;
            break;
        }
        double qx, qy, z2;
        if (triple(PySequence_Fast_GET_ITEM(rows, i), &qx, &qy, &z2) < 0) {
            rc = -1;
            break;
        }
        double d2 = py_square(qx - x) + py_square(qy - y) + z2;
        if (d2 > worst)
            worst = d2;
    }
    Py_DECREF(rows);
    Py_DECREF(members);
    if (rc < 0)
        return NULL;
    if (worst < 0.0) {  /* (math.sqrt's domain error; NaN passes as NaN) */
        PyErr_SetString(PyExc_ValueError, "math domain error");
        return NULL;
    }
    return PyFloat_FromDouble(sqrt(worst));
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
    {"disc_vertices", (PyCFunction)(void (*)(void))disc_vertices, METH_FASTCALL,
     "planners.collect.reach.disc_vertices (the same floats)."},
    {"vertex_on_rim", (PyCFunction)(void (*)(void))vertex_on_rim, METH_FASTCALL,
     "planners.collect.reach.vertex_on_rim (the same vertex)."},
    {"welzl_2d", (PyCFunction)(void (*)(void))welzl_2d_, METH_FASTCALL,
     "planners.core.geometry._welzl_2d (the same circle and support)."},
    {"reach_of", (PyCFunction)(void (*)(void))reach_of, METH_FASTCALL,
     "planners.deploy.cluster.reach_of (the same float)."},
    {"score_candidates", (PyCFunction)(void (*)(void))score_candidates, METH_FASTCALL,
     "planners.collect.path.score_candidates (the same floats)."},
    {"quickest", (PyCFunction)(void (*)(void))quickest, METH_FASTCALL,
     "planners.collect.path.quickest (the same candidate)."},
    {"route_times", (PyCFunction)(void (*)(void))route_times, METH_FASTCALL,
     "planners.collect.path.route_times (the same floats)."},
    {"deploy_times", (PyCFunction)(void (*)(void))deploy_times, METH_FASTCALL,
     "planners.deploy.path.deploy_times (the same floats)."},
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
    if (PyType_Ready(&StepperType) < 0 || PyType_Ready(&HopperType) < 0 || PyType_Ready(&LegType) < 0
        || PyType_Ready(&CirclesType) < 0 || PyType_Ready(&DeployCostType) < 0
        || PyType_Ready(&CollectCostType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL)
        return NULL;
    if (PyModule_AddObjectRef(m, "Stepper", (PyObject *)&StepperType) < 0
        || PyModule_AddObjectRef(m, "Hopper", (PyObject *)&HopperType) < 0
        || PyModule_AddObjectRef(m, "Leg", (PyObject *)&LegType) < 0
        || PyModule_AddObjectRef(m, "Circles", (PyObject *)&CirclesType) < 0
        || PyModule_AddObjectRef(m, "DeployStopCost", (PyObject *)&DeployCostType) < 0
        || PyModule_AddObjectRef(m, "CollectStopCost", (PyObject *)&CollectCostType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
