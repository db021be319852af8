"""The compiled kernels, when the install could build them (``planners/core/_native_src/*.c``, an
optional extension of ``setup.py``), else None: callers then run their pure-Python twins.

Each kernel computes the same floats as its Python twin (the same operations in the same order,
no fused multiply-adds), so a plan does not depend on which one ran; tests compare them.
``FLEETCTL_PURE_PYTHON=1`` in the environment turns the kernels off (to compare, or to profile the
Python code)."""

from __future__ import annotations

import os
from types import ModuleType


def _load() -> ModuleType | None:
    if os.environ.get("FLEETCTL_PURE_PYTHON", "") not in ("", "0"):
        return None
    try:
        from planners.core import _native
    except ImportError:
        return None
    return _native if hasattr(_native, "Stepper") else None  # (not a stray module of that name)


kernels: ModuleType | None = _load()
