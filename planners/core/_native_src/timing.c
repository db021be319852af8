/* The time model's carrier hop and rover leg (planners.core.timing): Stepper, Hopper, Leg. */
#include "native.h"

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

PyTypeObject StepperType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Stepper",
    .tp_doc = "Stepper(max_speed, accel|None, turn_rate|None): carrier_stepper's step(dx, dy, heading)",
    .tp_basicsize = sizeof(StepperObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(StepperObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_new = stepper_new,
};

PyTypeObject HopperType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Hopper",
    .tp_doc = "Hopper(max_speed, accel|None, turn_rate|None): carrier_hopper's hop(p, q, heading)",
    .tp_basicsize = sizeof(StepperObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(StepperObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_new = hopper_new,
};

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

PyTypeObject LegType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "planners.core._native.Leg",
    .tp_doc = "Leg(max_speed, accel|None, fixed_time): leg_timer's leg(length)",
    .tp_basicsize = sizeof(LegObject),
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL,
    .tp_vectorcall_offset = offsetof(LegObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_new = leg_new,
};
