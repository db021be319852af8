/* Routes (planners.collect.path, planners.deploy.path, planners.deploy.cluster): the collection's quick
 * placement, the routes' times, the deployment's longest flight from a stop. */
#include "native.h"

/* score_candidates(step, cands, prev, heading, nxt): planners.collect.path.score_candidates, per
 * candidate stop (stop, hop time into it, heading there, hop time on to nxt or None) */
PyObject *
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
PyObject *
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
PyObject *
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
PyObject *
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

/* reach_of(rows, members, x, y): planners.deploy.cluster.reach_of, the longest flight from (x, y)
 * on the ground to the members' rows (x, y, z²) */
PyObject *
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
