"""The reconnect helper the run's bus and ``fleetctl watch`` share (fleetctl.bus.reconnect), against
a real mosquitto: attempts at a broker that is not there are told and backed off, doubling up to
BACKOFF_MAX; the broker coming up ends the retries with a connected client and resets the back-off.
The connection states are the BusStatus members docs/mqtt.md names."""

from __future__ import annotations

import asyncio
import re
from pathlib import Path

import aiomqtt
import pytest

from fleetctl.bus.config import BACKOFF_MAX, BACKOFF_MIN, BusStatus
from fleetctl.bus.reconnect import MAX_ERROR_TEXT, ConnectionStatus, Reconnector
from tests.bus.test_bus import MOSQUITTO, Broker

ROOT = Path(__file__).resolve().parents[2]


class Told:
    """What the reconnector told: each failure, and the back-off it was about to wait."""

    def __init__(self) -> None:
        self.failures: list[BaseException] = []
        self.waits: list[float] = []
        self.link: Reconnector | None = None

    def __call__(self, exc: BaseException) -> None:
        assert self.link is not None
        self.failures.append(exc)
        self.waits.append(self.link.delay)


@pytest.mark.slow
@pytest.mark.skipif(MOSQUITTO is None, reason="mosquitto binary not installed")
async def test_failed_attempts_back_off_then_a_broker_that_comes_up_connects(tmp_path: Path) -> None:
    broker = Broker(tmp_path)  # its port is free: nothing listens yet
    told = Told()
    link = told.link = Reconnector(lambda: aiomqtt.Client("127.0.0.1", broker.port, timeout=2.0), told)
    attempt = asyncio.create_task(link.connect())
    try:
        async with asyncio.timeout(30):
            while len(told.failures) < 3:
                await asyncio.sleep(0.05)
        assert not attempt.done()
        assert told.waits[:3] == [min(BACKOFF_MIN * 2 ** k, BACKOFF_MAX) for k in range(3)]
        assert all(isinstance(f, aiomqtt.MqttError | OSError | TimeoutError) for f in told.failures)
        broker.start()
        async with asyncio.timeout(30):
            client = await attempt
        assert link.delay == BACKOFF_MIN  # reset by the connection
        await client.publish("reconnect/test", b"up", qos=1, timeout=5)
        await link.close(client)
    finally:
        attempt.cancel()
        broker.stop()


def test_every_bus_status_is_documented() -> None:
    """docs/mqtt.md's connection-state paragraph names each state the code can report."""
    text = (ROOT / "docs" / "mqtt.md").read_text(encoding="utf-8")
    section = text[text.index("## Connection state"):]
    named = set(re.findall(r"`([a-z]+)`", section))
    assert {s.value for s in BusStatus} <= named, {s.value for s in BusStatus} - named


def test_the_status_changes_through_one_setter_that_keeps_the_reason() -> None:
    c = ConnectionStatus()
    assert c.status == BusStatus.CONNECTING and c.last_error is None
    assert c.change_status(BusStatus.RECONNECTING, ConnectionRefusedError("refused")) == BusStatus.CONNECTING
    assert c.change_status(BusStatus.RECONNECTING, TimeoutError()) is None  # no change: no event
    assert c.last_error == "TimeoutError"  # the latest reason, named by its type when it has no text
    assert c.change_status(BusStatus.CONNECTED) == BusStatus.RECONNECTING
    assert c.last_error == "TimeoutError"  # kept for the summary
    c.change_status(BusStatus.RECONNECTING, OSError("x" * 1000))
    assert c.last_error is not None and len(c.last_error) == MAX_ERROR_TEXT
