"""The optional compiled kernels (planners/core/_native.c). Everything else is in pyproject.toml.

``optional=True``: an install without a C compiler (or without Python's headers) warns and goes on;
the planners then run their pure-Python twins, which give the same plans (planners.core.native)."""

from setuptools import Extension, setup

setup(ext_modules=[Extension(
    "planners.core._native", ["planners/core/_native.c"], optional=True,
    # the same floats as the Python code: no fused multiply-adds, no fast-math reordering
    extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math"],
)])
