/* The module planners.core._native: its functions and types (planners.core.native loads it). */
#include "native.h"

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
