/* One stop moved, the others kept: the polishes' cost of a stop at (x, y)
 * (planners.deploy.stops.deploy_stop_cost, planners.collect.polish.collect_stop_cost). */
#include "native.h"

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

PyTypeObject DeployCostType = {
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

PyTypeObject CollectCostType = {
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
