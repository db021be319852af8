"""Open-space deployment (dissertation ch. 4): the path generator ``lee`` with its clusters, path
builder and plan builder, the two-task optimum and the baselines.

Nothing is imported here, so that the registry in ``planners`` loads a planner on first call.
"""
