"""The shared core every planner builds on: problem and plan types, the time model, geometry
(enclosing circles, 1D/2D searches), clustering, route moves and local search, the approach
height, the lower bounds and the exact reference for tiny instances.

Nothing is imported here: import the module you need (``planners.core.timing`` and so on).
"""
