"""``fleetctl replay RUN_DIR``: a run's records played back into the views, in mission time.

:func:`load_run` reads the run folder (``journal.jsonl``, ``mission.yaml`` and, when there,
``traffic.tlog`` and one ``traffic-<id>.tlog`` per further link: the vehicles' positions and
batteries as the controller heard them);
:func:`timeline` merges them into :class:`Step` s in mission seconds since the run started (on
the embedded simulator a record's ``T`` when it has one, else its Unix time from the run's start
times the run's speedup);
:class:`Player` applies them to a :class:`ReplayState` - the journal's records change vehicle
states, stops, plan and phase as the controller did, telemetry moves the vehicles - waiting
``ΔT / speed`` wall seconds between steps (``speed`` 0: no waiting at all).
"""

from __future__ import annotations

import asyncio
import bisect
import contextlib
import logging
from collections import Counter
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleetctl.geo import Origin, geodetic_to_local
from fleetctl.journal import JOURNAL_NAME, MISSION_COPY, JournalError, Record, read_journal
from fleetctl.mavlink.tlog import TlogBattery, TlogError, TlogPosition, read_telemetry
from fleetctl.mission import Mission, MissionError, load_mission
from fleetctl.mission.links import TLOG, link_tlogs, vehicle_links
from fleetctl.mission.teams import mission_teams
from fleetctl.run.energy import range_from_percent
from fleetctl.run.kinds import Ev, Phase, VehicleStatus
from fleetctl.run.state import Event, FleetState
from fleetctl.views.view import View

log = logging.getLogger(__name__)

TLOG_NAME = TLOG
CHUNK = 0.25  # wall s: the longest single wait, so the views see the clock move
YIELD_EVERY = 200  # steps between yields to the loop when playing as fast as possible
EN_ROUTE_SPEED = 0.3  # m/s: a climbing rover moving this fast horizontally is on its way
NOT_EVENTS = frozenset({Ev.STATUSTEXT})  # records with a text that the live view did not show


class ReplayError(Exception):
    """A run folder that cannot be played back (missing, not a run, unreadable)."""


@dataclass(frozen=True)
class Sample:
    """One vehicle's telemetry at Unix time ``t`` (from the ``.tlog``)."""

    t: float
    vehicle: str
    enu: tuple[float, float, float] | None = None
    latlon: tuple[float, float] | None = None
    alt: float | None = None
    speed: float | None = None
    battery_pct: float | None = None


@dataclass(frozen=True)
class Step:
    T: float  # mission seconds since the run started
    record: Record | None = None
    sample: Sample | None = None


@dataclass
class RunRecord:
    """What a run folder holds."""

    dir: Path
    mission: Mission
    records: list[Record]
    samples: list[Sample]
    t0: float  # Unix time of the run record
    speedup: float  # mission seconds per wall second of that run
    sim: bool = False  # flown on the embedded simulator (never resumed: its records' T is one clock)

    @property
    def origin(self) -> Origin | None:
        return self.mission.origin


def load_run(run_dir: str | Path) -> RunRecord:
    """Read a run folder; :class:`ReplayError` naming what is missing or broken."""
    d = Path(run_dir)
    if not d.is_dir():
        raise ReplayError(f"{d}: no such run folder")
    if not (d / JOURNAL_NAME).is_file():
        raise ReplayError(f"{d}: no {JOURNAL_NAME}: not a run folder (deploy/collect/run write one)")
    try:
        records = read_journal(d / JOURNAL_NAME)
    except JournalError as exc:
        raise ReplayError(f"corrupt journal: {exc}") from None
    if not records or records[0].get("kind") != Ev.RUN or not isinstance(records[0].get("t"), int | float):
        raise ReplayError(f"{d / JOURNAL_NAME}: does not start with a 'run' record: not a run's journal")
    if not (d / MISSION_COPY).is_file():
        raise ReplayError(f"{d}: no {MISSION_COPY} (the copy of the mission a run keeps): cannot place the "
                          "vehicles")
    try:
        mission = load_mission(d / MISSION_COPY)
    except MissionError as exc:
        raise ReplayError(f"{d / MISSION_COPY}: {exc}") from None
    speedup = records[0].get("speedup")
    samples = read_telemetry_logs(d, mission)
    return RunRecord(d, mission, records, samples, float(records[0]["t"]),
                     float(speedup) if isinstance(speedup, int | float) and speedup > 0 else 1.0,
                     records[0].get("sim") is True)


def read_telemetry_logs(d: Path, mission: Mission) -> list[Sample]:
    """The samples of every link's ``.tlog`` in run folder ``d``, in time order
    (:func:`fleetctl.mission.links.link_tlogs` names them). A run of several links recorded
    before the logs were split has only ``traffic.tlog``, with every link in it: read as one log."""
    names = link_tlogs(mission)
    split = len(names) == 1 or any((d / n).is_file() for n in names.values() if n != TLOG_NAME)
    if not split:
        return read_tlog(d / TLOG_NAME, mission) if (d / TLOG_NAME).is_file() else []
    samples: list[Sample] = []
    for key, name in names.items():
        if (d / name).is_file():
            samples += read_tlog(d / name, mission, link=key)
    return sorted(samples, key=lambda s: s.t)


def read_tlog(path: Path, mission: Mission, link: str | None = None) -> list[Sample]:
    """Vehicle positions and batteries from a ``.tlog`` (messages from the mission's system ids).
    ``link``: the log is that link's alone (its vehicles' system ids). Without it the log does not
    say which link a message came on: a system id the mission uses on several links names no one
    vehicle, and its messages are left out."""
    ids = _vehicles_by_sysid(mission) if link is None else _vehicles_on_link(mission, link)
    out: list[Sample] = []
    try:
        for item in read_telemetry(path):
            vid = ids.get(item.sysid)
            if vid is not None:
                out.append(_sample(item, vid, mission.origin))
    except TlogError as exc:
        raise ReplayError(str(exc)) from None
    return out


def _vehicles_by_sysid(mission: Mission) -> dict[int, str]:
    """System id -> vehicle id, every carrier and rover whose sysid no other vehicle uses (on
    another link)."""
    sysids = {t.carrier.id: t.carrier.sysid for t in mission_teams(mission)}
    sysids |= {u.id: u.sysid for u in mission.rovers.units}
    uses = Counter(sysids.values())
    return {sysid: vid for vid, sysid in sysids.items() if uses[sysid] == 1}


def _vehicles_on_link(mission: Mission, link: str) -> dict[int, str]:
    """System id -> vehicle id of the carriers and rovers on ``link``."""
    on_link = {vid for vid, key in vehicle_links(mission).items() if key == link}
    sysids = {t.carrier.id: t.carrier.sysid for t in mission_teams(mission)}
    sysids |= {u.id: u.sysid for u in mission.rovers.units}
    return {sysid: vid for vid, sysid in sysids.items() if vid in on_link}


def _sample(item: TlogPosition | TlogBattery, vid: str, origin: Origin | None) -> Sample:
    if isinstance(item, TlogBattery):
        return Sample(item.t, vid, battery_pct=item.pct)
    enu = geodetic_to_local(item.lat, item.lon, item.alt, origin) if origin is not None else None
    return Sample(item.t, vid, enu, (item.lat, item.lon), item.relative_alt, item.speed)


class MissionClock:
    """Unix time -> mission seconds of a run: ``(t - t0) x speedup``; on the embedded simulator,
    interpolated between the records that carry their ``T`` (the simulator's clock, which a loaded
    machine slows down) so that telemetry and records share the one time base."""

    def __init__(self, run: RunRecord) -> None:
        self.t0, self.speedup = run.t0, run.speedup
        timed = [r for r in run.records if _number(r.get("t")) and _number(r.get("T"))]
        pairs = sorted((float(r["t"]), float(r["T"])) for r in timed) if run.sim else []
        self.ts = [t for t, _ in pairs]
        self.Ts = [T for _, T in pairs]

    def __call__(self, unix: float) -> float:
        ts, Ts = self.ts, self.Ts
        if not ts:
            return max(0.0, (unix - self.t0) * self.speedup)
        k = bisect.bisect_left(ts, unix)
        if k == 0 or k == len(ts):  # before the first / after the last: the run's speedup
            i = 0 if k == 0 else len(ts) - 1
            return max(0.0, Ts[i] + (unix - ts[i]) * self.speedup)
        span = ts[k] - ts[k - 1]
        f = (unix - ts[k - 1]) / span if span > 0 else 1.0
        return Ts[k - 1] + f * (Ts[k] - Ts[k - 1])

    def of(self, rec: Record) -> float:
        """A record's mission time: its own ``T`` on the simulator, else by its Unix time. (Real
        vehicles' runs go by the wall clock: ``T`` starts again at 0 in a ``fleetctl resume``.)"""
        if self.ts and isinstance(rec.get("T"), int | float):
            return float(rec["T"])
        return self(float(rec["t"]) if isinstance(rec.get("t"), int | float) else self.t0)


def _number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def timeline(run: RunRecord) -> list[Step]:
    """Records and telemetry in mission-time order (records first at equal times)."""
    clock = MissionClock(run)
    steps = [Step(clock.of(r), record=r) for r in run.records]
    steps += [Step(clock(s.t), sample=s) for s in run.samples]
    steps.sort(key=lambda s: (s.T, s.record is None))
    return steps


class ReplayState(FleetState):
    """A :class:`FleetState` whose clock is the replay's mission time and whose changes come from
    the run's records (see :meth:`apply`)."""

    def __init__(self, mission: Mission) -> None:
        super().__init__(mission)
        self.dwell: float | None = mission.dwell  # the run record's --dwell overrides it
        self.now = 0.0
        self.mission_clock = lambda: self.now
        self._handlers: dict[str, Callable[[Record], None]] = {
            Ev.RUN: self._run, Ev.PHASE: self._phase, Ev.PLAN: self._plan, Ev.REPLAN: self._replan,
            Ev.CARRIER_STARTED: self._carrier_started, Ev.STOP_REACHED: self._stop_reached,
            Ev.CARRIER_RELEASED: self._released, Ev.ROVER_LAUNCHED: self._launched,
            Ev.TASK_REACHED: self._vehicle(VehicleStatus.ON_TASK),
            Ev.ROVER_LOADED: self._vehicle(VehicleStatus.LOADED),
            Ev.ROVER_REFUSED: self._vehicle(VehicleStatus.REFUSED), Ev.LINK_LOST: self._link(True),
            Ev.LINK_BACK: self._link(False), Ev.COMMAND: self._command, Ev.SUMMARY: self._summary,
            Ev.COLLECTION_STARTED: self._collection_started,
        }

    @property
    def mission_time(self) -> float:
        return self.now

    # -- steps ---------------------------------------------------------------------------------
    def apply(self, step: Step) -> None:
        self.now = max(self.now, step.T)
        if step.sample is not None:
            self._telemetry(step.sample)
        elif step.record is not None:
            rec = step.record
            handler = self._handlers.get(str(rec.get("kind")))
            if handler is not None:
                handler(rec)
            if isinstance(rec.get("text"), str) and rec.get("kind") not in NOT_EVENTS:
                self._tell(rec)

    def _tell(self, rec: Record) -> None:
        data = {k: v for k, v in rec.items() if k not in ("t", "elapsed", "kind", "vehicle", "text", "T")}
        vid = rec.get("vehicle") if isinstance(rec.get("vehicle"), str) else None
        ev = Event(float(rec.get("elapsed") or 0.0), str(rec["kind"]), vid, rec["text"], data,
                   float(rec.get("t") or 0.0), self.now)
        self.events.append(ev)
        for listener in list(self._listeners):
            listener(ev)

    def _telemetry(self, s: Sample) -> None:
        v = self.vehicles.get(s.vehicle)
        if v is None:
            return
        v.connected, v.link_age = True, 0.0
        if s.battery_pct is not None:
            v.battery_pct = s.battery_pct
            if v.role == "rover":
                with contextlib.suppress(ValueError):
                    v.range_m = range_from_percent(s.battery_pct, self.reserve, self.endurance_range)
        if s.enu is not None or s.latlon is not None:
            v.enu, v.latlon, v.alt, v.speed = s.enu, s.latlon, s.alt, s.speed
        if v.state == VehicleStatus.UNKNOWN and v.role == "rover":
            v.state = VehicleStatus.ON_DECK
        elif v.state == VehicleStatus.CLIMBING and (s.speed or 0.0) > EN_ROUTE_SPEED:
            v.state = VehicleStatus.EN_ROUTE

    # -- records -------------------------------------------------------------------------------
    def _run(self, rec: Record) -> None:
        if isinstance(rec.get("mission"), str):
            self.mission_name = rec["mission"]
        if _number(rec.get("dwell")):
            self.dwell = float(rec["dwell"])
        self.set_state(self.carrier_id, VehicleStatus.IDLE)

    def _phase(self, rec: Record) -> None:
        phase = str(rec.get("phase"))
        if phase == "dwell":
            self.set_phase(Phase.DWELL, self.dwell)
        else:
            self.set_phase(Phase.PLAN)

    def _plan(self, rec: Record) -> None:
        plan = rec.get("plan")
        if not isinstance(plan, dict):
            return
        stops, makespan = len(plan.get("stops") or []), float(plan.get("makespan") or 0.0)
        if self.phase == Phase.PLAN:
            self.set_phase(Phase.COLLECT if plan.get("kind") == "collect" else Phase.DEPLOY, makespan, stops)
        else:
            self.planned, self.stop_count, self.stop_index = self.elapsed + makespan, stops, 0
        self.set_plan(plan, None)

    def _replan(self, rec: Record) -> None:
        self.replans += 1
        self.last_replan = rec.get("text") if isinstance(rec.get("text"), str) else "replan"
        if isinstance(rec.get("new_plan"), dict):
            self.set_plan(rec["new_plan"], self.now)

    def _carrier_started(self, rec: Record) -> None:
        self.plan_started = self.phase_started = self.now
        self.stop_index = 1 if self.stop_count else 0
        self.set_state(self.carrier_id, VehicleStatus.DRIVING)

    def _collection_started(self, rec: Record) -> None:
        if self.plan_started is None:
            self.plan_started = self.now

    def _stop_reached(self, rec: Record) -> None:
        if isinstance(rec.get("stop"), int):
            self.stop_index = rec["stop"]
        self.set_state(self.carrier_id, VehicleStatus.HOLDING)

    def _released(self, rec: Record) -> None:
        if isinstance(rec.get("stop"), int) and rec["stop"] < self.stop_count:
            self.stop_index = rec["stop"] + 1
        self.set_state(self.carrier_id, VehicleStatus.DRIVING)

    def _launched(self, rec: Record) -> None:
        if isinstance(rec.get("vehicle"), str):
            self.set_state(rec["vehicle"], VehicleStatus.CLIMBING, task=rec.get("task"))

    def _vehicle(self, status: VehicleStatus) -> Callable[[Record], None]:
        def apply(rec: Record) -> None:
            if isinstance(rec.get("vehicle"), str):
                self.set_state(rec["vehicle"], status)
        return apply

    def _link(self, lost: bool) -> Callable[[Record], None]:
        def apply(rec: Record) -> None:
            v = self.vehicles.get(str(rec.get("vehicle")))
            if v is not None:
                v.lost = lost
        return apply

    def _command(self, rec: Record) -> None:
        """Collection: a rover told to start its mission flies back; told to land, it lands."""
        if self.phase != Phase.COLLECT or not isinstance(rec.get("vehicle"), str):
            return
        status = {"start_mission": VehicleStatus.RETURNING, "set_current": VehicleStatus.LANDED}.get(
            str(rec.get("command")))
        if status is not None and rec["vehicle"] != self.carrier_id:
            self.set_state(rec["vehicle"], status)

    def _summary(self, rec: Record) -> None:
        result = rec.get("result")
        self.phase = Phase.DONE if result == "complete" else (
            Phase.INTERRUPTED if rec.get("interrupted") or result == "interrupted" else Phase.FAILED)


Sleep = Callable[[float], Awaitable[Any]]


class Player:
    """Plays :class:`Step` s into a :class:`ReplayState`: ``speed`` mission seconds per wall second,
    0 = as fast as possible. ``sleep`` is the wall-clock wait (``asyncio.sleep``; tests give
    their own)."""

    def __init__(self, steps: list[Step], state: ReplayState, speed: float = 1.0,
                 sleep: Sleep = asyncio.sleep) -> None:
        self.steps = steps
        self.state = state
        self.speed = speed
        self.sleep = sleep
        self.slept = 0.0  # wall seconds waited in all

    async def play(self) -> None:
        for n, step in enumerate(self.steps):
            if self.speed > 0:
                await self._until(step.T)
            elif n % YIELD_EVERY == 0:
                await asyncio.sleep(0)
            self.state.apply(step)

    async def _until(self, T: float) -> None:
        st = self.state
        while st.now < T:
            dt = min(T - st.now, CHUNK * self.speed)
            await self.sleep(dt / self.speed)
            self.slept += dt / self.speed
            st.now += dt


async def replay(run: RunRecord, view: View | None, *, speed: float = 1.0, linger: float = 0.0,
                 sleep: Sleep = asyncio.sleep) -> ReplayState:
    """Play ``run`` into ``view`` (started and stopped here); ``linger`` wall seconds more at the end."""
    state = ReplayState(run.mission)
    player = Player(timeline(run), state, speed, sleep)
    if view is not None:
        view.start(state, None)
    try:
        await player.play()
        if linger > 0:
            await sleep(linger)
    finally:
        if view is not None:
            await view.stop()
    return state


__all__ = ["Player", "ReplayError", "ReplayState", "RunRecord", "Sample", "Step", "load_run",
           "read_telemetry_logs", "read_tlog", "replay", "timeline"]
