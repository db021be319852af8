"""The optional compiled kernels (planners/core/_native_src/*.c). Everything else is in pyproject.toml.

``optional=True``: an install without a C compiler (or without Python's headers) warns and goes on;
the planners then run their pure-Python twins, which give the same plans (planners.core.native)."""

from pathlib import Path

from setuptools import Extension, setup

HERE = Path(__file__).resolve().parent
SOURCES = sorted(p.relative_to(HERE).as_posix() for p in (HERE / "planners/core/_native_src").glob("*.c"))
if not SOURCES:
    raise SystemExit("setup.py: no C sources in planners/core/_native_src")

setup(ext_modules=[Extension(
    "planners.core._native", SOURCES, depends=["planners/core/_native_src/native.h"], optional=True,
    # the same floats as the Python code: no fused multiply-adds, no fast-math reordering
    extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math"],
)])
