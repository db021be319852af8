"""Open-space collection (dissertation ch. 5): the path generator ``lee`` with its instance, path
builder, polish and reach regions, the convex-program placement, the two-rover optimum, the
baselines and the collection lower bound.

Nothing is imported here, so that the registry in ``planners`` loads a planner on first call
(``convex`` needs SciPy).
"""
