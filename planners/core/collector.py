"""Fewer passes of Python's cyclic garbage collector while a plan is computed.

A planner allocates millions of small containers (tuples, lists, and the regions and circles it
caches for the plan's duration); at the interpreter's default threshold (a young-generation pass
every 700 allocations) the collector walks the growing caches again and again while they are all
still in use: some 15 % of a 1,000-rover collection plan's CPU time. ``fewer_collections`` raises
the young generation's threshold to ``PLANNING_THRESHOLD`` while any planner runs (the registries'
``planners.LazyPlanner`` enters it) and puts the thresholds found on entry back when the last one
returns, from any thread. The collector still runs, only less often, so what a plan leaves for it
(a collection plan's caches, once it returns, are freed by the collector) and a long anytime
search's garbage are still freed; the plans are the same. At 20,000 the collector still took
about 11 ms of a 1,000-rover collection plan's 160 ms (a pass over the young caches every few
thousand regions); at 200,000 about 1 ms, for at most some 200,000 unreachable containers
(tens of megabytes) waiting for the next pass.
"""

from __future__ import annotations

import gc
import threading
from collections.abc import Iterator
from contextlib import contextmanager

PLANNING_THRESHOLD = 200_000  # allocations between young-generation passes while planning

_lock = threading.Lock()
_active = 0  # planner calls running (nested or in other threads)
_saved: tuple[int, int, int] = (700, 10, 10)


@contextmanager
def fewer_collections() -> Iterator[None]:
    """The collector's young-generation threshold at least ``PLANNING_THRESHOLD`` inside; the
    thresholds found on entry restored when the last planner call (of any thread) leaves."""
    global _active, _saved
    with _lock:
        if _active == 0:
            _saved = gc.get_threshold()
            gc.set_threshold(max(PLANNING_THRESHOLD, _saved[0]), *_saved[1:])
        _active += 1
    try:
        yield
    finally:
        with _lock:
            _active -= 1
            if _active == 0:
                gc.set_threshold(*_saved)
