"""Planning among obstacles on a probabilistic roadmap (dissertation ch. 6): the workspace and
roadmap (``graph``; shapely, SciPy), the world both graph planners share, and the deployment and
collection graph planners.

Nothing is imported here: shapely and SciPy load only when a graph planner is first called.
"""
