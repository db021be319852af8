"""Stopping owned tasks (:func:`fleetctl.aio.cancel_and_wait`) without swallowing a cancel of the
caller, and the supervisor's queue reader (:func:`fleetctl.run.events.next_event`) that hung an
operation on ArduPilot when its watcher was cancelled while it tidied up."""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from fleetctl.aio import cancel_and_wait
from fleetctl.run.events import next_event


async def _cancel_after(coro_loop: asyncio.Task[None], steps: int) -> bool:
    """Cancel ``coro_loop`` after ``steps`` turns of the event loop; True when it then ends."""
    for _ in range(steps):
        await asyncio.sleep(0)
    coro_loop.cancel()
    done, _ = await asyncio.wait({coro_loop}, timeout=1.0)
    return bool(done) and coro_loop.cancelled()


@pytest.mark.parametrize("steps", range(12))
async def test_a_watcher_polling_the_event_queue_ends_when_cancelled_at_any_moment(steps: int) -> None:
    # a loop polling the queue with no timeout to spare: every turn of the loop is either waiting,
    # or tidying up the queue reader (where a swallowed cancel kept it polling forever)
    queue: asyncio.Queue[object] = asyncio.Queue()
    stop = False

    async def watch() -> None:
        while not stop:  # (ends a watcher that swallowed its cancel: the test fails, not hangs)
            await next_event(queue, set(), 0)  # type: ignore[arg-type]

    task = asyncio.ensure_future(watch())
    try:
        assert await _cancel_after(task, steps)
    finally:
        stop = True
        await asyncio.wait({task}, timeout=1.0)


async def test_cancel_and_wait_ends_the_tasks_and_keeps_their_errors_to_themselves() -> None:
    async def fails() -> None:
        raise RuntimeError("boom")

    async def sleeps() -> None:
        await asyncio.sleep(60)

    failed = asyncio.ensure_future(fails())
    await asyncio.sleep(0)
    sleeping = asyncio.ensure_future(sleeps())
    await cancel_and_wait(failed, sleeping, None)
    assert sleeping.cancelled()
    with pytest.raises(RuntimeError):  # still there for its owner to read
        failed.result()


async def test_a_cancel_of_the_caller_while_it_waits_is_passed_on() -> None:
    release = asyncio.Event()

    async def slow_to_stop() -> None:  # takes a while to end once cancelled
        try:
            await asyncio.sleep(60)
        finally:
            with contextlib.suppress(asyncio.CancelledError):
                await release.wait()

    async def owner() -> str:
        child = asyncio.ensure_future(slow_to_stop())
        await asyncio.sleep(0)
        await cancel_and_wait(child, timeout=30.0)
        return "ran on"

    task = asyncio.ensure_future(owner())
    await asyncio.sleep(0.01)
    task.cancel()  # reaches the owner while it waits for its child
    done, _ = await asyncio.wait({task}, timeout=1.0)
    release.set()
    assert done and task.cancelled()


async def test_a_task_that_will_not_end_is_left_after_the_timeout(caplog: pytest.LogCaptureFixture) -> None:
    enough = asyncio.Event()

    async def stubborn() -> None:
        while not enough.is_set():
            with contextlib.suppress(asyncio.CancelledError):
                await enough.wait()

    task = asyncio.ensure_future(stubborn())
    task.set_name("stubborn")
    await asyncio.sleep(0)
    await cancel_and_wait(task, timeout=0.05)
    assert not task.done() and "stubborn did not end" in caplog.text
    enough.set()
    await task
