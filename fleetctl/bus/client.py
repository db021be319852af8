"""The MQTT fleet bus: telemetry, events and plans out; task changes in (on aiomqtt).

Topics under the mission's prefix ``P`` (default ``fleetctl/<mission name>``):

* ``P/status`` (retained, QoS 1) - ``{"status": "online" | "done" | "failed" | "interrupted" |
  "offline", "mission", "phase", "stop", "stops", "planned", "elapsed", "bus", "carrier", "t"}``
  plus :attr:`FleetBus.identity` (a team's id and session); the broker publishes the last will
  ``{"status": "offline", "mission", **identity}`` when the controller vanishes;
* ``P/plan`` (retained, QoS 1) - the current plan JSON (``fleetctl.plan/1``);
* ``P/vehicles/<id>/telemetry`` (QoS 0) - one vehicle's state at ``telemetry_hz`` (2 Hz);
* ``P/events`` (QoS 1) - every journal record as written to ``journal.jsonl``;
* ``P/errors`` (QoS 1) - answers to rejected task messages;
* in: ``P/tasks/add`` (``{"tasks": [{"id", "position" | "lat"/"lon"/"alt"}, ...]}``, a list of
  tasks or one task), ``P/tasks/remove`` (``{"tasks": ["t1", ...]}``, a list of ids or one id) and,
  for a long operation, ``P/tasks/update`` (``{"tasks": [{"id", "duration", "work"}, ...]}``: a
  task's new work), decoded and checked like the mission file (:mod:`fleetctl.bus.task_messages`)
  and handed to ``Executor.submit_task_change``.
* more topics a caller subscribes with :meth:`FleetBus.subscribe` (the team coordination,
  :mod:`fleetctl.run.teams.link`) and publishes with ``publish(..., absolute=True)``.

The bus never holds up flying: publishing only appends to a bounded buffer (oldest dropped and
counted when full; retained topics keep only their latest value and are never dropped), one
background task owns the connection, reconnects with exponential backoff and drains the buffer.
The password is read from the environment variable ``password_env`` names and is never logged,
journaled or put in a summary.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import asdict
from typing import TYPE_CHECKING, Any, Protocol

import aiomqtt

from fleetctl.aio import cancel_and_wait
from fleetctl.bus.config import (
    BUFFER_SIZE,
    FINAL_STATES,
    MAX_MESSAGE,
    MAX_PENDING,
    PUBLISH_TIMEOUT,
    STATUS_EVENT,
    STATUS_INTERVAL,
    TELEMETRY_HZ,
    BusConfig,
    BusConfigError,
    BusStatus,
    Secret,
    bus_config,
    client_kwargs,
    parse_url,
)
from fleetctl.bus.reconnect import CONNECTION_ERRORS, ConnectionStatus, Reconnector
from fleetctl.bus.task_messages import TaskMessageError, TaskRules, decode_task_json
from fleetctl.journal import Journal, Record, json_safe
from fleetctl.kinds import Ev
from fleetctl.mission.model import TaskWork

if TYPE_CHECKING:
    from fleetctl.mission import Mission
    from fleetctl.run.state import FleetState
    from fleetctl.views.view import View
    from planners.core.problem import Task

log = logging.getLogger(__name__)


class TaskChanges(Protocol):
    """What task messages are handed to: the run's executor (:mod:`fleetctl.run.executor`)."""

    def submit_task_change(self, add: list[Task], remove: list[str], source: str,
                           work: dict[str, TaskWork] | None = None,
                           retime: dict[str, TaskWork] | None = None) -> None: ...

def _dumps(data: Any) -> bytes:
    return json.dumps(json_safe(data), separators=(",", ":")).encode()


class FleetBus(ConnectionStatus):
    """One run's connection to the broker (see the module docstring)."""

    def __init__(self, config: BusConfig, mission: Mission) -> None:
        self.config = config
        self.mission = mission
        self.prefix = config.topic_prefix
        self.dropped = 0
        self.published = 0
        self.connects = 0
        self.disconnects = 0  # connections lost after they were up
        self.state: FleetState | None = None
        self.executor: TaskChanges | None = None
        self.record: Callable[..., None] = lambda kind, **data: None  # the journal's write
        self.tasks: list[Task] = list(mission.tasks)  # the task set task messages are checked against
        self._buf: deque[tuple[str, bytes, int]] = deque()
        self._retained: dict[str, bytes] = {}
        self._dirty: list[str] = []  # retained topics to (re)publish, in order
        self._wake = asyncio.Event()
        self._tasks: list[asyncio.Task[None]] = []
        self._last_status: tuple[Any, ...] | None = None
        self._last_status_t = 0.0
        self._final: str | None = None
        self._on_status: list[Callable[[BusStatus], None]] = []
        self.rejected = 0  # task messages answered on P/errors
        self.failed: str | None = None  # why the bus task stopped (it should never)
        # changes (add, remove, topic, added tasks' work) before an executor exists
        self._pending: deque[tuple[list[Task], list[str], str, dict[str, TaskWork], dict[str, TaskWork]]] = \
            deque()
        self.identity: dict[str, Any] = {}  # fields of every status, the last will too (a team's id, session)
        self._handlers: list[tuple[str, Callable[[str, bytes], None]]] = []  # extra subscriptions
        self.refuse_tasks: str | None = None  # why every task message is refused (None: they are handled)
        self.rules = TaskRules(mission, self.current_tasks, self._work_of)  # what a task message may change

    # -- outgoing ---------------------------------------------------------------------------------
    def topic(self, suffix: str) -> str:
        return f"{self.prefix}/{suffix}"

    def publish(self, suffix: str, payload: Any, *, retain: bool = False, qos: int = 0,
                absolute: bool = False) -> None:
        """Queue a message (never waits). Retained topics keep only their latest payload;
        ``absolute``: ``suffix`` is the whole topic (not under the prefix)."""
        topic = suffix if absolute else self.topic(suffix)
        data = payload if isinstance(payload, bytes) else _dumps(payload)
        if retain:
            self._retained[topic] = data
            if topic not in self._dirty:
                self._dirty.append(topic)
        else:
            if len(self._buf) >= self.config.buffer_size:
                self._buf.popleft()
                self.dropped += 1
            self._buf.append((topic, data, qos))
        self._wake.set()

    def on_record(self, rec: Record) -> None:
        """A :class:`fleetctl.journal.Journal` observer: every record to ``events``, plans to ``plan``."""
        self.publish("events", rec, qos=1)
        kind = rec.get("kind")
        plan = rec.get("plan") if kind == "plan" else rec.get("new_plan") if kind == "replan" else None
        if isinstance(plan, dict):
            self.publish("plan", plan, retain=True, qos=1)
        source = rec.get("source")
        if kind == "task_change_rejected" and isinstance(source, str) and source.startswith("mqtt:"):
            # refused later by the replanner (e.g. no rover left on the deck): answer the sender too
            topic = source[len("mqtt:"):]
            error = f"refused by the controller: {rec.get('reason')}"
            self.publish("errors", {"topic": topic, "error": error, "t": rec.get("t")}, qos=1)

    def status_payload(self, status: str | None = None) -> dict[str, Any]:
        st = self.state
        out: dict[str, Any] = {"status": status or self._final or "online", "mission": self.mission.name,
                               **self.identity, "t": round(time.time(), 3), "rejected": self.rejected}
        if st is not None:
            out.update(phase=st.phase, stop=st.stop_index, stops=st.stop_count, planned=st.planned,
                       elapsed=round(st.elapsed, 2))
            c = st.vehicles.get(st.carrier_id)
            if c is not None:
                out["carrier"] = {"id": c.id, "state": c.state, "lost": c.lost,
                                  "enu": [round(x, 2) for x in c.enu] if c.enu is not None else None}
        return out

    def subscribe(self, topic_filter: str, handler: Callable[[str, bytes], None]) -> None:
        """Also subscribe to ``topic_filter`` (a whole topic, wildcards allowed; QoS 1, again on
        every reconnect) and hand each message's topic and payload (at most MAX_MESSAGE + 1 bytes)
        to ``handler``, in its own error boundary. Call before :meth:`start`."""
        self._handlers.append((topic_filter, handler))

    def status_line(self) -> str:
        """``bus: connected`` / ``bus: reconnecting (12 dropped)`` for the live view."""
        extra = [self.last_error] if self.status != BusStatus.CONNECTED and self.last_error else []
        extra += [f"{len(self._buf)} queued"] if self.status != BusStatus.CONNECTED and self._buf else []
        if self.dropped:
            extra.append(f"{self.dropped} dropped")
        line = f"bus: {self.status} {self.config.url} {self.prefix}"
        return line + (f" ({', '.join(extra)})" if extra else "")

    def stats(self) -> dict[str, Any]:
        """The summary's ``"mqtt"`` section (docs/summary-json.md)."""
        return {"url": self.config.url, "topic_prefix": self.prefix, "state": self.status,
                "connects": self.connects, "disconnects": self.disconnects, "last_error": self.last_error,
                "published": self.published, "dropped": self.dropped, "queued": len(self._buf),
                "rejected": self.rejected}

    def _set_status(self, status: BusStatus, error: BaseException | None = None) -> None:
        old = self.change_status(status, error)
        if old is None:
            return
        log.info("bus %s: %s", self.config.url, status)
        if self.state is not None:  # a broker that never answers is shown too (was silent)
            self.state.event(STATUS_EVENT[status], self._status_text(old), None, url=self.config.url,
                             dropped=self.dropped, error=self.last_error)
        for cb in list(self._on_status):
            cb(status)

    def _status_text(self, old: BusStatus) -> str:
        url = self.config.url
        if self.status == BusStatus.CONNECTED:
            return f"bus: connected to {url}" + (f" ({self.dropped} dropped)" if self.dropped else "")
        why = f" ({self.last_error})" if self.last_error else ""
        if old == BusStatus.CONNECTED:
            return f"bus: connection to {url} lost{why}; reconnecting, messages are queued"
        return f"bus: cannot connect to {url}{why}; retrying, messages are queued (the mission flies on)"

    def add_status_listener(self, cb: Callable[[BusStatus], None]) -> None:
        self._on_status.append(cb)

    # -- life cycle -------------------------------------------------------------------------------
    def start(self, state: FleetState | None = None, record: Callable[..., None] | None = None) -> None:
        """Connect in the background (needs a running loop); publish telemetry from ``state``;
        ``record`` (the journal's ``write``) journals accepted and rejected task messages."""
        self.state = state
        if record is not None:
            self.record = record
        self.publish("status", self.status_payload("online"), retain=True, qos=1)
        loop = asyncio.get_running_loop()
        run = loop.create_task(self._run(), name="mqtt bus")
        run.add_done_callback(self._on_run_done)
        self._tasks.append(run)
        if state is not None:
            tel = loop.create_task(self._telemetry(), name="mqtt telemetry")
            tel.add_done_callback(self._on_run_done)
            self._tasks.append(tel)

    def follow(self, state: FleetState, record: Callable[..., None]) -> None:
        """A bus that outlives the runs publishing on it (a team's in a run of several teams, one
        run per phase): telemetry and status from ``state`` from now on, task records to ``record``
        (started with :meth:`start` first)."""
        self.state, self.record, self.executor = state, record, None
        if self.status in (BusStatus.CONNECTED, BusStatus.RECONNECTING, BusStatus.FAILED):  # where it stands
            text = self._status_text(BusStatus.CONNECTED if self.connects else BusStatus.CONNECTING)
            state.event(STATUS_EVENT[self.status], text, None, url=self.config.url, dropped=self.dropped,
                        error=self.last_error)
        if not any(t.get_name() == "mqtt telemetry" and not t.done() for t in self._tasks):
            tel = asyncio.get_running_loop().create_task(self._telemetry(), name="mqtt telemetry")
            tel.add_done_callback(self._on_run_done)
            self._tasks.append(tel)

    async def unfollow(self) -> None:
        """The run :meth:`follow` followed has ended: its last telemetry goes out and telemetry stops
        (the bus goes on, its status stays the last one) until the next :meth:`follow`."""
        self._publish_telemetry()
        self.executor = None
        tel = [t for t in self._tasks if t.get_name() == "mqtt telemetry"]
        await cancel_and_wait(*tel)
        for t in tel:
            self._tasks.remove(t)

    def attach_executor(self, executor: TaskChanges) -> None:
        """Task messages go to ``executor.submit_task_change`` from now on; changes queued before
        (a controller still connecting or planning) are handed on now, in order."""
        self.executor = executor
        pending, self._pending = list(self._pending), deque()
        submit = getattr(executor, "submit_task_change", None)
        for add, remove, topic, work, retime in pending:
            try:
                if submit is None:
                    raise TaskMessageError("task changes are not supported by this controller "
                                           "(no replanner); nothing changed")
                submit(add=add, remove=remove, source=f"mqtt:{topic}", work=work,
                       **({"retime": retime} if retime else {}))
            except Exception as exc:  # noqa: BLE001 - the sender's answer, never the bus's end
                self._answer_error(topic, b"", f"queued change refused by the controller: {exc}")
                continue
            self.record(Ev.BUS_TASK_CHANGE, op="queued", add=sorted(t.id for t in add), remove=remove,
                        topic=topic)

    def _on_run_done(self, task: asyncio.Task[None]) -> None:
        """The bus's tasks never end by themselves: if one does, say so (journal, view, status)."""
        if task.cancelled() or task.exception() is None:
            return
        exc = task.exception()
        why = f"{type(exc).__name__}: {exc}"
        log.error("bus %s: %s stopped: %s", self.config.url, task.get_name(), why, exc_info=exc)
        if task.get_name() != "mqtt bus":  # telemetry: the connection itself goes on
            text = f"bus: telemetry stopped ({why}); events and task changes still go over MQTT"
            kind = Ev.BUS_TELEMETRY_FAILED
        else:
            self.failed = why
            self.change_status(BusStatus.FAILED)
            text = f"bus: stopped ({why}); no telemetry or task changes over MQTT for the rest of the run"
            kind = Ev.BUS_FAILED
        if self.state is not None:
            self.state.event(kind, text, None, url=self.config.url)
        with contextlib.suppress(Exception):
            self.record(kind, error=why)
        if kind == "bus_failed":
            for cb in list(self._on_status):
                with contextlib.suppress(Exception):
                    cb(BusStatus.FAILED)

    def show_in(self, view: View | None) -> None:
        """Put :meth:`status_line` into a live view that shows status lines."""
        add = getattr(view, "add_status", None)
        if add is not None:
            add(self.status_line)

    async def aclose(self, final: str = "done", flush_timeout: float = 3.0) -> None:
        """Publish the final status (and flush the buffer) if connected, then disconnect."""
        for t in self._tasks[1:]:  # telemetry first
            t.cancel()
        self._publish_telemetry()  # the final state of every vehicle
        deadline = time.monotonic() + flush_timeout
        while (self.status == BusStatus.CONNECTED and (self._dirty or self._buf)
               and time.monotonic() < deadline):
            await asyncio.sleep(0.02)  # the last events go out before the final status
        self._final = final if final in FINAL_STATES else "failed"
        self.publish("status", self.status_payload(), retain=True, qos=1)
        while self.status == BusStatus.CONNECTED and self._dirty and time.monotonic() < deadline + 1.0:
            await asyncio.sleep(0.02)
        await cancel_and_wait(*self._tasks)
        self._tasks.clear()
        self.change_status(BusStatus.CLOSED)

    # -- the connection ---------------------------------------------------------------------------
    async def _run(self) -> None:
        ctx = await asyncio.to_thread(self.config.ssl_context)
        will = aiomqtt.Will(self.topic("status"),
                            _dumps({"status": "offline", "mission": self.mission.name, **self.identity}),
                            qos=1, retain=True)

        def make() -> aiomqtt.Client:
            return aiomqtt.Client(identifier=self.config.client_id, will=will,
                                  max_queued_outgoing_messages=self.config.buffer_size,
                                  **client_kwargs(self.config, ctx))

        link = Reconnector(make, self._cannot_connect)
        while True:
            client = await link.connect()
            self.connects += 1
            try:
                await self._connected(client)
            except* CONNECTION_ERRORS as eg:
                log.debug("bus %s: connection lost: %s", self.config.url, eg.exceptions[0])
                self.disconnects += 1
                self._set_status(BusStatus.RECONNECTING, eg.exceptions[0])
            except* Exception as eg:  # a bug must not end the bus: say so, reconnect
                log.error("bus %s: unexpected error, reconnecting: %r", self.config.url, eg.exceptions[0],
                          exc_info=eg.exceptions[0])
                with contextlib.suppress(Exception):
                    self.record(Ev.BUS_ERROR, error=f"{type(eg.exceptions[0]).__name__}: {eg.exceptions[0]}")
                self.disconnects += 1
                self._set_status(BusStatus.RECONNECTING, eg.exceptions[0])
                await link.back_off()
            finally:
                await link.close(client)

    def _cannot_connect(self, exc: BaseException) -> None:
        log.debug("bus %s: cannot connect: %s", self.config.url, exc)
        self._set_status(BusStatus.RECONNECTING, exc)

    async def _connected(self, client: aiomqtt.Client) -> None:
        """Subscribe, then send and receive until the connection drops."""
        self._dirty = list(self._retained)  # the broker may have lost them
        await client.subscribe([(self.topic("tasks/add"), 1), (self.topic("tasks/remove"), 1),
                                (self.topic("tasks/update"), 1)]
                               + [(f, 1) for f, _ in self._handlers], timeout=PUBLISH_TIMEOUT)
        self._set_status(BusStatus.CONNECTED)
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self._send(client))
            tg.create_task(self._receive(client))

    async def _send(self, client: aiomqtt.Client) -> None:
        while True:
            while self._dirty:
                topic = self._dirty[0]
                data = self._retained[topic]
                await client.publish(topic, data, qos=1, retain=True, timeout=PUBLISH_TIMEOUT)
                if self._dirty and self._dirty[0] == topic and self._retained[topic] is data:
                    self._dirty.pop(0)
                self.published += 1
            if self._buf:
                item = self._buf[0]
                await client.publish(item[0], item[1], qos=item[2], timeout=PUBLISH_TIMEOUT)
                if self._buf and self._buf[0] is item:
                    self._buf.popleft()
                self.published += 1
                continue
            self._wake.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._wake.wait(), 1.0)

    async def _receive(self, client: aiomqtt.Client) -> None:
        async for msg in client.messages:
            try:  # every message in its own error boundary: one bad message never stops the bus
                topic = msg.topic.value
                raw = msg.payload
                payload = (bytes(raw) if isinstance(raw, bytes | bytearray)
                           else str(raw).encode()[:MAX_MESSAGE + 1])
                handler = next((h for f, h in self._handlers if msg.topic.matches(f)), None)
                if handler is not None:
                    handler(topic, payload[:MAX_MESSAGE + 1])
                else:
                    self.handle_task_message(topic, payload)
            except Exception:  # noqa: BLE001 - handle_task_message answers everything; this is a last guard
                log.exception("bus: a message could not be handled")

    async def _telemetry(self) -> None:
        assert self.state is not None
        period = 1.0 / self.config.telemetry_hz
        while True:
            st = self.state
            now = time.monotonic()
            self._publish_telemetry()
            key = (st.phase, st.stop_index, st.stop_count, st.planned, self.status)
            if key != self._last_status or now - self._last_status_t >= STATUS_INTERVAL:
                self._last_status, self._last_status_t = key, now
                self.publish("status", self.status_payload() | {"bus": self.status}, retain=True, qos=1)
            await asyncio.sleep(period)

    def _publish_telemetry(self) -> None:
        if self.state is None:
            return
        t = round(time.time(), 3)
        for vid, v in list(self.state.vehicles.items()):
            self.publish(f"vehicles/{vid}/telemetry", asdict(v) | {"t": t}, qos=0)

    # -- incoming task changes ------------------------------------------------------------------------
    def handle_task_message(self, topic: str, payload: bytes) -> bool:
        """Validate and apply one ``tasks/add`` or ``tasks/remove`` message; a bad one is answered on
        ``errors``, counted (:attr:`rejected`) and changes nothing. Never raises. Returns whether
        the change was handed on (or queued for the controller)."""
        try:
            return self._handle_task_message(topic, payload)
        except TaskMessageError as exc:
            self._answer_error(topic, payload, str(exc))
        except Exception as exc:  # noqa: BLE001 - whatever a message holds, the bus goes on
            log.exception("bus: task message on %s", topic)
            self._answer_error(topic, payload, f"cannot handle the message ({type(exc).__name__}: {exc}); "
                                               "nothing changed")
        return False

    def _handle_task_message(self, topic: str, payload: bytes) -> bool:
        op = topic.rsplit("/", 1)[-1]
        data, force = self._decode_task_message(payload)
        work: dict[str, TaskWork] = {}
        retime: dict[str, TaskWork] = {}
        add: list[Task] = []
        remove: list[str] = []
        if op == "add":
            add, work = self.rules.add(data, topic)
        elif op == "remove":
            remove = self.rules.remove(data)
        elif op == "update":
            retime = self.rules.update(data, topic)
        else:
            raise TaskMessageError(f"unknown topic {topic!r}")
        if not force:
            why = self.rules.absurd(add, remove)
            if why is not None:
                raise TaskMessageError(f'{why}; nothing changed (send "force": true in the message to '
                                       "apply it anyway)")
        self._hand_over(add, remove, topic, work, retime)
        ids = {t.id for t in add}
        self.tasks = [t for t in self.current_tasks() if t.id not in remove] + list(add)
        self.record(Ev.BUS_TASK_CHANGE, op=op, add=sorted(ids), remove=remove, topic=topic,
                    **({"update": sorted(retime)} if retime else {}),
                    **({"queued": True} if self.executor is None else {}),
                    **({"force": True} if force else {}))
        return True

    def _decode_task_message(self, payload: bytes) -> tuple[Any, bool]:
        """A task message's JSON and its ``force`` flag, once the mission accepts task changes and
        the message is within the size and nesting limits (:class:`TaskMessageError` otherwise)."""
        if len(payload) > MAX_MESSAGE:
            raise TaskMessageError(f"message of {len(payload)} bytes is larger than {MAX_MESSAGE}")
        if self.refuse_tasks is not None:
            raise TaskMessageError(self.refuse_tasks)
        if not self.config.accept_task_changes:
            raise TaskMessageError(
                "task changes over MQTT are off for this mission; to allow them set "
                "'accept_task_changes: true' in the mission's mqtt section (and let only named users "
                "publish to <prefix>/tasks/# on the broker: docs/mqtt.md); nothing changed")
        return decode_task_json(payload)

    def _hand_over(self, add: list[Task], remove: list[str], topic: str, work: dict[str, TaskWork],
                   retime: dict[str, TaskWork]) -> None:
        """The change to the controller, or queued for it while it is still connecting or planning."""
        submit = getattr(self.executor, "submit_task_change", None)
        if self.executor is None:
            if len(self._pending) >= MAX_PENDING:
                raise TaskMessageError(f"{MAX_PENDING} task changes are already waiting for the controller "
                                       "to start; try again when the plan is out")
            self._pending.append((add, remove, topic, work, retime))
        elif submit is None:
            raise TaskMessageError("task changes are not supported by this controller (no replanner); "
                                   "nothing changed")
        else:
            try:
                submit(add=add, remove=remove, source=f"mqtt:{topic}", work=work,
                       **({"retime": retime} if retime else {}))
            except Exception as exc:  # noqa: BLE001 - the replanner's refusal is the sender's answer
                raise TaskMessageError(f"refused by the controller: {exc}") from None

    def _answer_error(self, topic: str, payload: bytes, error: str) -> None:
        self.rejected += 1
        log.warning("bus: rejected %s: %s", topic, error[:500])
        text = payload[:500].decode("utf-8", "replace")
        self.publish("errors", {"topic": topic, "error": error, "payload": text, "t": round(time.time(), 3)},
                     qos=1)
        self.record(Ev.BUS_REJECTED, topic=topic, error=error)

    def current_tasks(self) -> list[Task]:
        """The live task set: the executor's (it changes with replans), else the bus's own view."""
        live = getattr(self.executor, "tasks", None)
        if isinstance(live, dict):
            return list(live.values())
        return list(self.tasks)

    def _work_of(self, task: str) -> TaskWork:
        """A task's work now: the running operation's (it changes), else the mission's."""
        live = getattr(getattr(self.executor, "operation_phase", None), "changes", None)
        tasks = getattr(live, "tasks", None)
        if isinstance(tasks, dict) and task in tasks:
            return TaskWork(tasks[task].duration, tasks[task].ground)
        return self.mission.task_work(task)

def start_bus(mission: Mission, config: BusConfig | None, journal: Journal, state: FleetState,
              view: View | None = None, prepare: Callable[[FleetBus], None] | None = None) -> FleetBus | None:
    """Start the bus of a run (``config``, else the mission's ``mqtt:`` section; None when off):
    every journal record goes out on ``events``, telemetry from ``state``, the status line into
    ``view``; ``prepare`` is called with the bus before it starts (identity, subscriptions). A bad
    setting is reported as an event and the mission flies without the bus."""
    if config is None:
        try:
            config = bus_config(mission)
        except BusConfigError as exc:
            state.event(Ev.BUS_ERROR, f"bus: off ({exc})")
            return None
    if config is None:
        return None
    bus = FleetBus(config, mission)
    if prepare is not None:
        prepare(bus)
    journal.add_observer(bus.on_record)
    bus.show_in(view)
    bus.start(state, journal.write)
    journal.write(Ev.BUS, url=config.url, topic_prefix=config.topic_prefix, username=config.username,
                  tls=config.tls)
    return bus


def iter_topics(prefix: str) -> Iterable[str]:
    """The topics ``fleetctl watch`` subscribes to: the controller's, and every team's under
    ``<prefix>/teams/<team>/`` (docs/mqtt.md)."""
    kinds = ("status", "plan", "vehicles/+/telemetry", "events")
    return (*(f"{prefix}/{k}" for k in kinds), *(f"{prefix}/teams/+/{k}" for k in kinds))


__all__ = ["BUFFER_SIZE", "TELEMETRY_HZ", "BusConfig", "BusConfigError", "FleetBus", "Secret",
           "TaskMessageError", "bus_config", "client_kwargs", "iter_topics", "parse_url", "start_bus"]
