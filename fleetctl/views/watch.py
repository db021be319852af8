"""``fleetctl watch``: the live view of a mission flown by another process, from the MQTT bus alone.

:class:`Watcher` subscribes to ``<prefix>/status``, ``/plan``, ``/vehicles/+/telemetry`` and
``/events`` (see :mod:`fleetctl.bus.client`), keeps a :class:`RemoteFleetState` up to date and the
dashboard (:func:`fleetctl.views.dashboard.render`) draws it; ``--headless`` prints the operator events
instead and the fleet table when it ends. The connection is retried with backoff like the bus's.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import sys
from dataclasses import fields
from types import SimpleNamespace
from typing import IO, Any

import aiomqtt

from fleetctl.bus.config import (
    BACKOFF_MAX,
    BACKOFF_MIN,
    CONNECT_TIMEOUT,
    FINAL_STATES,
    BusConfig,
    client_kwargs,
)
from fleetctl.run.state import Event, FleetState, VehicleState
from fleetctl.views.dashboard import HeadlessView, LiveView, plain_text, render
from fleetctl.views.view import View, Views

log = logging.getLogger(__name__)

_VEHICLE_FIELDS = {f.name for f in fields(VehicleState)}


class RemoteFleetState(FleetState):
    """A :class:`FleetState` filled from the bus instead of a live fleet (no mission file needed)."""

    def __init__(self, mission_name: str = "?", max_events: int = 12) -> None:
        # FleetState builds its vehicles from a Mission; here they come from telemetry
        nobody = SimpleNamespace(name=mission_name, carrier=SimpleNamespace(id="", sysid=0), tasks=(),
                                 rovers=SimpleNamespace(reserve=0.0, endurance_range=0.0, units=(),
                                                        motion=lambda: None))
        super().__init__(nobody, max_events=max_events)  # type: ignore[arg-type]
        self.vehicles = {}
        self.remote_status: str | None = None  # online | done | failed | interrupted | offline
        self.remote_elapsed = 0.0
        self.plan: dict[str, Any] | None = None
        self.records = 0  # journal records seen on <prefix>/events
        self.remote_T = 0.0  # the latest mission time (T+) seen in an event

    @property
    def elapsed(self) -> float:  # the controller's mission clock as last reported
        return self.remote_elapsed

    @property
    def mission_time(self) -> float:  # T+ of the latest event the controller journalled
        return self.remote_T

    def add_event(self, rec: dict[str, Any]) -> Event | None:
        """A journal record from ``<prefix>/events``; operator events (with a text) are kept and
        told to the listeners."""
        self.records += 1
        text = rec.get("text")
        if not isinstance(text, str):
            return None
        data = {k: v for k, v in rec.items() if k not in ("t", "elapsed", "kind", "vehicle", "text")}
        elapsed = rec.get("elapsed")
        mission_t = rec.get("T")
        if isinstance(mission_t, int | float):  # else (a vehicle's STATUSTEXT): the latest T seen
            self.remote_T = max(self.remote_T, float(mission_t))
        mission_t = float(mission_t) if isinstance(mission_t, int | float) else self.remote_T
        ev = Event(float(elapsed) if isinstance(elapsed, int | float) else 0.0, str(rec.get("kind", "?")),
                   rec.get("vehicle") if isinstance(rec.get("vehicle"), str) else None, text, data,
                   float(rec.get("t", 0.0)) if isinstance(rec.get("t"), int | float) else 0.0, mission_t)
        self.events.append(ev)
        for listener in list(self._listeners):
            try:
                listener(ev)
            except Exception:  # noqa: BLE001
                log.exception("event listener failed")
        return ev

    def update_vehicle(self, vid: str, data: dict[str, Any]) -> None:
        v = self.vehicles.get(vid)
        if v is None:
            sysid = data.get("sysid")
            v = VehicleState(vid, str(data.get("role", "rover")), sysid if isinstance(sysid, int) else 0)
            self.vehicles[vid] = v
        for k, val in data.items():
            if k in _VEHICLE_FIELDS and k != "id":
                if k == "enu" and isinstance(val, list):
                    val = tuple(val)
                setattr(v, k, val)
        if v.role == "carrier":
            self.carrier_id = vid
        # carrier first, then rovers in the order first heard
        if self.carrier_id and next(iter(self.vehicles)) != self.carrier_id:
            self.vehicles = {self.carrier_id: self.vehicles[self.carrier_id],
                             **{k: x for k, x in self.vehicles.items() if k != self.carrier_id}}

    def update_status(self, data: dict[str, Any]) -> None:
        self.remote_status = str(data.get("status", "online"))
        if isinstance(data.get("mission"), str):
            self.mission_name = data["mission"]
        if isinstance(data.get("phase"), str):
            self.phase = data["phase"]
        if isinstance(data.get("stop"), int):
            self.stop_index = data["stop"]
        if isinstance(data.get("stops"), int):
            self.stop_count = data["stops"]
        if "planned" in data:
            self.planned = data["planned"] if isinstance(data["planned"], int | float) else None
        if isinstance(data.get("elapsed"), int | float):
            self.remote_elapsed = float(data["elapsed"])


class Watcher:
    """Keeps a :class:`RemoteFleetState` up to date from the bus."""

    def __init__(self, config: BusConfig, state: RemoteFleetState | None = None) -> None:
        self.config = config
        self.prefix = config.topic_prefix
        self.state = state or RemoteFleetState()
        self.status = "connecting"
        self.last_error: str | None = None
        self.connects = 0
        self.messages = 0
        self.finished = asyncio.Event()  # set when the controller's status is final

    def status_lines(self) -> list[str]:
        why = f" ({self.last_error})" if self.last_error and self.status != "connected" else ""
        out = [f"bus: {self.status} {self.config.url} {self.prefix}{why}"
               + (f" · controller {self.state.remote_status}" if self.state.remote_status else
                  " · no controller status yet")]
        plan = self.state.plan
        if plan:
            out.append(f"plan: {plan.get('kind', '?')} ({plan.get('planner', '?')}), "
                       f"{len(plan.get('stops') or [])} stops, makespan {plan.get('makespan', 0.0):.1f} s")
        return out

    def _set_status(self, status: str, error: BaseException | None = None) -> None:
        """Track the connection; every change is an event (a dead broker is not silent)."""
        if error is not None:
            self.last_error = (str(error) or type(error).__name__)[:300]
        if status == self.status:
            return
        old, self.status = self.status, status
        url, why = self.config.url, f" ({self.last_error})" if self.last_error else ""
        if status == "connected":
            self.connects += 1
            text = f"bus: connected to {url}, watching {self.prefix}/#"
        elif old == "connected":
            text = f"bus: connection to {url} lost{why}; reconnecting"
        else:
            text = f"bus: cannot connect to {url}{why}; retrying"
        self.state.event(f"bus_{status}", text, None, url=url, error=self.last_error)

    def handle(self, topic: str, payload: bytes) -> None:
        """Apply one message of the bus to the state."""
        self.messages += 1
        rel = topic[len(self.prefix) + 1:] if topic.startswith(self.prefix + "/") else topic
        try:
            data = json.loads(payload)
        except (ValueError, UnicodeDecodeError):
            data = payload.decode("utf-8", "replace").strip()
        st = self.state
        if rel == "status":
            st.update_status(data if isinstance(data, dict) else {"status": str(data)})
            if st.remote_status in FINAL_STATES:
                self.finished.set()
            else:
                self.finished.clear()
        elif rel == "plan" and isinstance(data, dict):
            st.plan = data
        elif rel == "events" and isinstance(data, dict):
            st.add_event(data)
        elif rel.startswith("vehicles/") and rel.endswith("/telemetry") and isinstance(data, dict):
            st.update_vehicle(rel[len("vehicles/"):-len("/telemetry")], data)

    async def run(self) -> None:
        """Connect (retrying with backoff) and apply messages until cancelled."""
        ctx = await asyncio.to_thread(self.config.ssl_context)
        delay = BACKOFF_MIN
        topics = [(f"{self.prefix}/{t}", 1) for t in ("status", "plan", "vehicles/+/telemetry", "events")]
        while True:
            client = aiomqtt.Client(identifier=self.config.client_id, **client_kwargs(self.config, ctx))
            try:
                async with asyncio.timeout(CONNECT_TIMEOUT * 2):
                    await client.__aenter__()
            except (aiomqtt.MqttError, TimeoutError, OSError) as exc:
                log.debug("watch %s: cannot connect: %s", self.config.url, exc)
                self._set_status("reconnecting", exc)
                await asyncio.sleep(delay)
                delay = min(delay * 2, BACKOFF_MAX)
                continue
            delay = BACKOFF_MIN
            try:
                await client.subscribe(topics, timeout=CONNECT_TIMEOUT)
                self._set_status("connected")
                async for msg in client.messages:
                    p = msg.payload
                    data = bytes(p) if isinstance(p, bytes | bytearray) else str(p).encode()
                    self.handle(msg.topic.value, data)
            except (aiomqtt.MqttError, TimeoutError, OSError) as exc:
                log.debug("watch %s: connection lost: %s", self.config.url, exc)
                self._set_status("reconnecting", exc)
            except asyncio.CancelledError:
                self.status = "stopped"
                raise
            finally:
                with contextlib.suppress(Exception):
                    async with asyncio.timeout(1.0):
                        await client.__aexit__(None, None, None)


def render_text(watcher: Watcher, width: int | None = None) -> str:
    """The dashboard of ``watcher`` as plain text (for ``--headless`` and tests): uncut lines
    without a ``width`` (:func:`fleetctl.views.dashboard.plain_text`)."""
    return plain_text(render(watcher.state, None, watcher.status_lines(), width=width), width)


async def watch(config: BusConfig, *, headless: bool = False, exit_on_done: bool = False,
                out: IO[str] | None = None, latlon: bool = False, extra_view: View | None = None) -> int:
    """Show the mission on ``config``'s bus until cancelled (Ctrl-C) or, with ``exit_on_done``,
    until the controller's status is final (done, failed, interrupted, offline). ``extra_view``
    (the web map) is fed the same state. Returns 0."""
    out = out or sys.stdout
    watcher = Watcher(config)
    view: View
    if headless:
        view = HeadlessView(out)
        out.write(f"watching {config.url} {config.topic_prefix}/# (Ctrl-C to stop)\n")
        out.flush()
    else:
        live = LiveView(latlon=latlon)
        live.add_status(lambda: " · ".join(watcher.status_lines()))
        view = live
    if extra_view is not None:
        view = Views(view, extra_view)
    view.start(watcher.state, None)
    runner = asyncio.create_task(watcher.run(), name="watch bus")
    try:
        while True:
            if exit_on_done:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(watcher.finished.wait(), 1.0)
                if watcher.finished.is_set():
                    break
            else:
                await asyncio.sleep(1.0)
            if runner.done():
                runner.result()  # an unexpected error: raise it
    finally:
        runner.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await runner
        await view.stop()
        if headless:
            out.write(render_text(watcher))
            out.flush()
    return 0


__all__ = ["RemoteFleetState", "Watcher", "render_text", "watch"]
