"""``fleetctl watch``: the live view of a mission flown by another process, from the MQTT bus alone.

:class:`Watcher` subscribes to ``<prefix>/status``, ``/plan``, ``/vehicles/+/telemetry`` and
``/events`` (see :mod:`fleetctl.bus.client`), and to the same four under ``<prefix>/teams/+/``
(the teams of a run of several, docs/mqtt.md), keeps a :class:`RemoteFleetState` up to date for
the controller and one for each team it hears of, and the dashboard draws them (one state as
:func:`fleetctl.views.dashboard.render`, several teams as
:func:`~fleetctl.views.dashboard.render_teams`); ``--headless`` prints the operator events instead
(a team's prefixed with it) and the fleet table when it ends. The connection is retried with
backoff like the bus's.

Everything on the bus is outside input: a message over :data:`MAX_PAYLOAD` bytes, a team id that
is not 1 to 64 characters of ``A-Z a-z 0-9 . _ -``, a team beyond
:data:`~fleetctl.views.teams.MAX_TEAMS` and a vehicle beyond :data:`MAX_VEHICLES` per state are
ignored (counted in :attr:`Watcher.ignored`).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import re
import sys
from collections.abc import Callable
from dataclasses import fields
from types import SimpleNamespace
from typing import IO, Any

import aiomqtt

from fleetctl.aio import cancel_and_wait
from fleetctl.bus.client import iter_topics
from fleetctl.bus.config import (
    CONNECT_TIMEOUT,
    FINAL_STATES,
    STATUS_EVENT,
    BusConfig,
    BusStatus,
    client_kwargs,
)
from fleetctl.bus.reconnect import CONNECTION_ERRORS, ConnectionStatus, Reconnector
from fleetctl.run.state import Event, FleetState, VehicleState
from fleetctl.views.dashboard import HeadlessView, LiveView, plain_text, render_teams
from fleetctl.views.teams import MAX_TEAMS, ShownTeams
from fleetctl.views.view import View, Views

log = logging.getLogger(__name__)

_VEHICLE_FIELDS = {f.name for f in fields(VehicleState)}
MAX_PAYLOAD = 1 << 20  # bytes of one message (a plan of many stops is the largest)
MAX_VEHICLES = 1024  # vehicles kept per state
ID_RE = re.compile(r"[A-Za-z0-9_.-]{1,64}")  # a team's id in a topic or a status


class RemoteFleetState(FleetState):
    """A :class:`FleetState` filled from the bus instead of a live fleet (no mission file needed)."""

    def __init__(self, mission_name: str = "?", max_events: int = 12) -> None:
        # FleetState builds its vehicles from a Mission; here they come from telemetry
        carrier = SimpleNamespace(id="", sysid=0, deck_height=0.0)
        nobody = SimpleNamespace(name=mission_name, carrier=carrier, tasks=(),
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

    def update_vehicle(self, vid: str, data: dict[str, Any]) -> bool:
        """Apply a vehicle's telemetry; False (ignored) for a new vehicle beyond :data:`MAX_VEHICLES`
        or with an id over 64 characters."""
        v = self.vehicles.get(vid)
        if v is None:
            if len(self.vehicles) >= MAX_VEHICLES or not 0 < len(vid) <= 64:
                return False
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
        return True

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


class Watcher(ConnectionStatus):
    """Keeps a :class:`RemoteFleetState` up to date from the bus: the controller's
    (:attr:`state`) and each team's (:attr:`teams`)."""

    def __init__(self, config: BusConfig, state: RemoteFleetState | None = None) -> None:
        self.config = config
        self.prefix = config.topic_prefix
        self.state = state or RemoteFleetState()
        self.teams: dict[str, RemoteFleetState] = {}  # P/teams/<team>/...: each team's
        self.shown = ShownTeams()  # what the views draw: the controller's state, then the teams'
        self.shown.set_main(self.state)
        self.on_team: Callable[[str, RemoteFleetState], None] | None = None  # a team first heard of
        self.on_teams: Callable[[list[str]], None] | None = None  # the teams a run's status names
        self.connects = 0
        self.messages = 0
        self.ignored = 0  # messages ignored (too large, a bad team id, too many teams or vehicles)
        self.finished = asyncio.Event()  # set when the controller's status is final

    def status_lines(self) -> list[str]:
        why = f" ({self.last_error})" if self.last_error and self.status != BusStatus.CONNECTED else ""
        out = [f"bus: {self.status} {self.config.url} {self.prefix}{why}"
               + (f" · controller {self.state.remote_status}" if self.state.remote_status else
                  " · no controller status yet")]
        plan = self.state.plan
        if plan:
            out.append(f"plan: {plan.get('kind', '?')} ({plan.get('planner', '?')}), "
                       f"{len(plan.get('stops') or [])} stops, makespan {plan.get('makespan', 0.0):.1f} s")
        if self.teams:
            out.append("teams: " + ", ".join(f"{t} {self.teams[t].remote_status or '?'}"
                                             for t in self.shown.order if t in self.teams))
        return out

    def _set_status(self, status: BusStatus, error: BaseException | None = None) -> None:
        """Track the connection; every change is an event (a dead broker is not silent)."""
        old = self.change_status(status, error)
        if old is None:
            return
        url, why = self.config.url, f" ({self.last_error})" if self.last_error else ""
        if status == BusStatus.CONNECTED:
            self.connects += 1
            text = f"bus: connected to {url}, watching {self.prefix}/#"
        elif old == BusStatus.CONNECTED:
            text = f"bus: connection to {url} lost{why}; reconnecting"
        else:
            text = f"bus: cannot connect to {url}{why}; retrying"
        self.state.event(STATUS_EVENT[status], text, None, url=url, error=self.last_error)

    def handle(self, topic: str, payload: bytes) -> None:
        """Apply one message of the bus to the state (the controller's, or a team's)."""
        self.messages += 1
        if len(payload) > MAX_PAYLOAD:
            self.ignored += 1
            return
        rel = topic[len(self.prefix) + 1:] if topic.startswith(self.prefix + "/") else topic
        try:
            data = json.loads(payload)
        except (ValueError, UnicodeDecodeError, RecursionError):
            data = payload.decode("utf-8", "replace").strip()
        st = self.state
        if rel.startswith("teams/"):
            team, _, rel = rel[len("teams/"):].partition("/")
            found = self._team(team)
            if found is None:
                self.ignored += 1
                return
            st = found
        if not self._apply(st, rel, data):
            self.ignored += 1
        self._check_finished()

    def _apply(self, st: RemoteFleetState, rel: str, data: Any) -> bool:
        if rel == "status":
            st.update_status(data if isinstance(data, dict) else {"status": str(data)})
            if st is self.state and isinstance(data, dict) and isinstance(data.get("teams"), list):
                self._declare(data["teams"])
        elif rel == "plan" and isinstance(data, dict):
            st.plan = data
        elif rel == "events" and isinstance(data, dict):
            st.add_event(data)
        elif rel.startswith("vehicles/") and rel.endswith("/telemetry") and isinstance(data, dict):
            return st.update_vehicle(rel[len("vehicles/"):-len("/telemetry")], data)
        return True

    def _declare(self, teams: list[Any]) -> None:
        ids = [t for t in teams[:MAX_TEAMS] if isinstance(t, str) and ID_RE.fullmatch(t)]
        changed = self.shown.order[:len(ids)] != ids
        self.shown.declare(ids, every=True)
        if changed and self.on_teams is not None:
            self.on_teams(ids)

    def _team(self, team: str) -> RemoteFleetState | None:
        """The state of ``team`` (made when first heard of); None for a bad id or too many teams."""
        st = self.teams.get(team)
        if st is not None:
            return st
        if not ID_RE.fullmatch(team) or len(self.teams) >= MAX_TEAMS:
            return None
        st = self.teams[team] = RemoteFleetState(self.state.mission_name)
        self.shown.set_team(team, st)
        if self.on_team is not None:
            self.on_team(team, st)
        return st

    def _check_finished(self) -> None:
        """Finished: the controller's status is final; without one (controllers of one team each
        under ``P/teams/``), every team's."""
        top = self.state.remote_status
        if top is not None:
            done = top in FINAL_STATES
        else:
            done = bool(self.teams) and all(t.remote_status in FINAL_STATES for t in self.teams.values())
        if done:
            self.finished.set()
        else:
            self.finished.clear()

    async def run(self) -> None:
        """Connect (retrying with backoff) and apply messages until cancelled."""
        ctx = await asyncio.to_thread(self.config.ssl_context)
        topics = [(t, 1) for t in iter_topics(self.prefix)]

        def make() -> aiomqtt.Client:
            return aiomqtt.Client(identifier=self.config.client_id, **client_kwargs(self.config, ctx))

        link = Reconnector(make, self._cannot_connect)
        while True:
            client = await link.connect()
            try:
                await self._follow(client, topics)
            except CONNECTION_ERRORS as exc:
                log.debug("watch %s: connection lost: %s", self.config.url, exc)
                self._set_status(BusStatus.RECONNECTING, exc)
            except asyncio.CancelledError:  # stopped while connected (not connected: the reason stays)
                self.change_status(BusStatus.STOPPED)
                raise
            finally:
                await link.close(client)

    def _cannot_connect(self, exc: BaseException) -> None:
        log.debug("watch %s: cannot connect: %s", self.config.url, exc)
        self._set_status(BusStatus.RECONNECTING, exc)

    async def _follow(self, client: aiomqtt.Client, topics: list[tuple[str, int]]) -> None:
        """Subscribe, then apply every message until the connection drops."""
        await client.subscribe(topics, timeout=CONNECT_TIMEOUT)
        self._set_status(BusStatus.CONNECTED)
        async for msg in client.messages:
            p = msg.payload
            data = bytes(p) if isinstance(p, bytes | bytearray) else str(p).encode()
            self.handle(msg.topic.value, data)


def render_text(watcher: Watcher, width: int | None = None) -> str:
    """The dashboard of ``watcher`` as plain text (for ``--headless`` and tests): uncut lines
    without a ``width`` (:func:`fleetctl.views.dashboard.plain_text`)."""
    return plain_text(render_teams(watcher.shown, None, watcher.status_lines(), width=width), width)


async def watch(config: BusConfig, *, headless: bool = False, exit_on_done: bool = False,
                out: IO[str] | None = None, latlon: bool = False, extra_view: View | None = None,
                watcher: Watcher | None = None) -> int:
    """Show the mission on ``config``'s bus until cancelled (Ctrl-C) or, with ``exit_on_done``,
    until the controller's status is final (done, failed, interrupted, offline). ``extra_view``
    (the web map) is fed the same states; ``watcher`` (tests) is the :class:`Watcher` to use. Returns 0."""
    out = out or sys.stdout
    watcher = watcher or Watcher(config)
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
    watcher.on_teams = lambda teams: view.declare_teams(teams, every=True)
    watcher.on_team = lambda team, st: view.start_team(team, st, None)
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
        await cancel_and_wait(runner)
        await view.stop()
        if headless:
            out.write(render_text(watcher))
            out.flush()
    return 0


__all__ = ["RemoteFleetState", "Watcher", "render_text", "watch"]
