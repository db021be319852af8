/* What the compiled kernels share (planners.core.native): reading Python numbers, CPython's own
 * arithmetic (hypot, x ** 2, float %), the time model's step and leg, the module's functions and types.
 *
 * Every kernel is the C twin of a pure-Python function named in its comment, with the same
 * floating-point operations in the same order (the build turns off contraction into fused
 * multiply-adds, -ffp-contract=off), so that a plan is the same float for float with or without
 * the kernels. planners/core/native.py loads them when the install could compile them and falls
 * back to the Python functions otherwise; tests compare both on random inputs. */
#ifndef PLANNERS_NATIVE_H
#define PLANNERS_NATIVE_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* ---- reading Python numbers ---- */

static inline int
as_double(PyObject *o, double *x)
{
    *x = PyFloat_Check(o) ? PyFloat_AS_DOUBLE(o) : PyFloat_AsDouble(o);
    return (*x == -1.0 && PyErr_Occurred()) ? -1 : 0;
}

static inline int
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

static inline PyObject *
point(double x, double y)
{
    PyObject *px = PyFloat_FromDouble(x), *py = PyFloat_FromDouble(y);
    PyObject *out = (px && py) ? PyTuple_Pack(2, px, py) : NULL;
    Py_XDECREF(px);
    Py_XDECREF(py);
    return out;
}

static inline int
triple(PyObject *t, double *a, double *b, double *c)
{
    return (item_double(t, 0, a) < 0 || item_double(t, 1, b) < 0 || item_double(t, 2, c) < 0) ? -1 : 0;
}

/* ---- CPython's arithmetic ---- */

/* Python's x ** 2: the C library's pow(x, 2.0), which is not always x * x; called through a
 * pointer the compiler cannot see through, so that it does not turn it into x * x */
static double (*volatile pow_fn)(double, double) = pow;

static inline double
py_square(double x)
{
    return pow_fn(x, 2.0);
}

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

static inline double
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

#define INSIDE_TOL 1e-9  /* planners.collect.reach.INSIDE_TOL */

/* ---- the time model (timing.c): the carrier's step and the rover's leg ---- */

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

extern PyTypeObject StepperType, HopperType, LegType;

/* ---- the module's functions (module.c lists them) and types ---- */

PyObject *two_opt_small(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *farthest_flight(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *hypot_(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *project_discs(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *rim(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *clip_segment(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *disc_vertices(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *vertex_on_rim(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *score_candidates(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *quickest(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *route_times(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *deploy_times(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *welzl_2d_(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
PyObject *reach_of(PyObject *self, PyObject *const *args, Py_ssize_t nargs);
int farthest_of(PyObject *rows, double x, double y, double *out);

extern PyTypeObject DeployCostType, CollectCostType, CirclesType;

#endif
