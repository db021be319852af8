/* Power-weighted enclosing circles (planners.core.geometry): Welzl's loop and EnclosingCircles,
 * the circles of subsets of one set of points remembered by membership and derived from a
 * neighbouring subset's support. */
#include "native.h"

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

PyTypeObject CirclesType = {
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
PyObject *
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
