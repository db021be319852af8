"""asyncio helpers shared by the layers.

:func:`cancel_and_wait` is how a task owned by another (a watcher, a background loop, a helper
future) is stopped. The obvious ``task.cancel()`` then ``with suppress(CancelledError): await task``
swallows a cancel that reaches the *caller* while it waits there: the caller runs on as if nothing
happened, and whoever cancelled it waits for it forever (an operation on ArduPilot hung that way
when the carrier reached a stop in the moment its way-watcher was tidying up its queue reader).
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

log = logging.getLogger(__name__)

CANCEL_WAIT = 5.0  # wall s a cancelled task is given to end


async def cancel_and_wait(*tasks: asyncio.Future[Any] | None, timeout: float = CANCEL_WAIT) -> None:
    """Cancel ``tasks`` (None and finished ones are skipped) and wait, at most ``timeout`` wall
    seconds, for them to end. How they end (cancelled, an error) is not raised here - a task's
    error is its owner's to read with ``result()`` - but a cancel of the caller is. A task still
    running after ``timeout`` is logged and left."""
    running = [t for t in tasks if t is not None and not t.done()]
    for t in running:
        t.cancel()
    if running:
        _done, late = await asyncio.wait(running, timeout=timeout)
        for t in late:
            name = t.get_name() if isinstance(t, asyncio.Task) else repr(t)
            log.warning("%s did not end within %g s of being cancelled", name, timeout)
    for f in tasks:
        if f is not None and f.done() and not f.cancelled():
            f.exception()  # looked at: no "exception was never retrieved" when its owner does not


__all__ = ["CANCEL_WAIT", "cancel_and_wait"]
