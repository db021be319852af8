"""The operator's view of a run: a live terminal dashboard (rich) or, ``--headless``, one log
line per event.

:class:`LiveView` redraws from :class:`fleetctl.run.state.FleetState` a few times a second in a
task of its own (``rich.live.Live`` without its refresh thread), so the view never blocks the
mission; :class:`HeadlessView` prints each event as it happens. :func:`make_view` picks one.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import sys
from collections.abc import Callable, Sequence
from typing import IO, TYPE_CHECKING, Any

from rich.console import Console, Group, JustifyMethod
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from fleetctl.run.kinds import Ev
from fleetctl.run.state import Event, FleetState, VehicleState
from fleetctl.views.eta import FLYING, PlannedLeg, mission_time_to_go, planned_legs, time_to_go
from fleetctl.views.levels import STYLE, battery_level, link_level
from fleetctl.views.view import View

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet

REFRESH_HZ = 4.0
AIRBORNE_HEIGHT = 0.3  # m above home: a rover this high is in the air (fleetctl.run.launch)

_STATE_STYLE = {
    "on_deck": "cyan", "climbing": "yellow", "en_route": "yellow", "on_task": "green", "returning": "yellow",
    "landed": "magenta", "loaded": "green", "lost": "bold red", "refused": "red", "holding": "blue",
    "driving": "yellow", "idle": "dim",
}


def _num(v: float | None, fmt: str = "{:.1f}") -> str:
    return "–" if v is None else fmt.format(v)


def tplus(t: float | None) -> str:
    """The one time base of the views: mission seconds since the run started, ``T+12.3s``."""
    return "T+–" if t is None else f"T+{t:.1f}s"


ALERT_KINDS = frozenset({"error", "rover_refused", "link_lost", "task_unserved", "rover_failed",
                         "task_change_rejected", Ev.WEB_FAILED})
HEADER_LINES = 2  # title line and progress bar
MAX_EVENTS = 8


def _header(state: FleetState) -> Table:
    elapsed, planned = state.elapsed, state.planned
    head = Table.grid(padding=(0, 2))
    for _ in range(3):
        head.add_column()
    stop = f"stop {state.stop_index}/{state.stop_count}" if state.stop_count else ""
    togo = mission_time_to_go(state)
    clock = tplus(state.mission_time) + ("" if togo is None else f"  to go {togo:.1f} s")
    bar: Any = ProgressBar(total=max(planned or 1.0, 1e-6), completed=min(elapsed, planned or 0.0), width=24)
    head.add_row(Text(f"{state.mission_name} · {state.phase}", style="bold"), Text(stop), Text(clock))
    phase = f"{state.phase} elapsed {elapsed:.1f} s" + (f" / planned {planned:.1f} s" if planned else "")
    if state.eta is not None and planned and abs(state.eta - planned) >= 0.05:
        phase += f" · ETA {state.eta:.1f} s"  # the live makespan prediction (docs/time-model.md)
    head.add_row(Text(phase, style="dim"), "", bar)
    if state.link_line:
        head.add_row(Text("link", style="bold"), Text(state.link_line, style=state.link_style), "")
    if state.replans:
        head.add_row(Text(f"replans {state.replans}", style="bold magenta"),
                     Text(state.last_replan or "", style="magenta", overflow="ellipsis"), "")
    return head


def _is_airborne(v: VehicleState) -> bool:
    return v.state in FLYING or v.on_ground is False or (v.alt or 0.0) > AIRBORNE_HEIGHT


def order_rows(state: FleetState, max_rows: int | None) -> tuple[list[VehicleState], int]:
    """The vehicles to show and how many are left out. When they do not all fit in ``max_rows``
    (the "… N more" line included): the carrier, then rovers in the air (moving ones first), then
    the rest."""
    rows = list(state.vehicles.values())
    if max_rows is None or len(rows) <= max_rows:
        return rows, 0
    def rank(v: VehicleState) -> int:
        if v.role == "carrier":
            return 0
        if _is_airborne(v):
            return 1 if v.state in FLYING else 2
        return 3
    keep = max(max_rows - 1, 0)
    ordered = sorted(rows, key=rank)  # stable: mission order within a rank
    return ordered[:keep], len(rows) - keep


def _columns(width: int | None, latlon: bool) -> list[tuple[str, JustifyMethod]]:
    wide = width is None or width >= 100
    pos: list[tuple[str, JustifyMethod]] = ([("lat", "right"), ("lon", "right")] if latlon else
                                            [("E m", "right"), ("N m", "right")])
    cols: list[tuple[str, JustifyMethod]] = [("id", "left")]
    if wide:
        cols.append(("role", "left"))
    cols += [("state", "left"), ("task", "left"), *pos, ("alt", "right")]
    if wide:
        cols.append(("m/s", "right"))
    cols.append(("batt%", "right"))
    if wide:
        cols.append(("range", "right"))
    cols += [("link", "right"), ("to go", "right")]
    return cols


def _cells(state: FleetState, v: VehicleState, cols: list[tuple[str, JustifyMethod]],
           legs: dict[str, PlannedLeg]) -> list[Any]:
    st = "lost" if v.lost else v.state
    batt = STYLE.get(battery_level(state, v), "")
    link = link_level(v)
    ttg = time_to_go(state, v, legs)
    ll = v.latlon
    values: dict[str, Any] = {
        "id": Text(v.id, style="bold" if v.role == "carrier" else ""), "role": v.role,
        "state": Text(st, style=_STATE_STYLE.get(st, "")), "task": v.task or "",
        "E m": _num(v.enu[0] if v.enu else None), "N m": _num(v.enu[1] if v.enu else None),
        "lat": _num(ll[0] if ll else None, "{:.6f}"), "lon": _num(ll[1] if ll else None, "{:.6f}"),
        "alt": _num(v.alt), "m/s": _num(v.speed),
        "batt%": Text(_num(v.battery_pct, "{:.0f}"), style=batt),
        "range": Text(_num(v.range_m, "{:.0f}"), style=batt),
        "link": Text("LOST" if link == "lost" else _num(v.link_age), style=STYLE.get(link, "")),
        "to go": _num(ttg, "{:.0f}s") if ttg is not None else "",
    }
    return [values[c] for c, _ in cols]


def _events(state: FleetState, count: int) -> Text:
    events = Text()
    for ev in list(state.events)[-count:] if count > 0 else []:
        events.append(f"{tplus(ev.mission_time):>9}  ", style="dim")
        events.append(ev.text + "\n", style="red" if ev.kind in ALERT_KINDS else "")
    return events


def render(state: FleetState, max_rows: int | None = None, status: Sequence[str] = (), *,
           latlon: bool = False, width: int | None = None, events: int = MAX_EVENTS) -> Group:
    """The dashboard for ``state``: header (phase, stop k of N, ``T+`` mission time and time to go,
    the phase's planned vs elapsed with a progress bar), one row per vehicle (at most ``max_rows``
    lines with "… N more"), the latest ``events``; ``status`` lines (e.g. the MQTT bus) under the
    header. ``width`` < 100 leaves out role, speed and range; ``latlon`` shows WGS84 instead of E/N."""
    table = Table(expand=False, pad_edge=False, box=None, header_style="bold")
    cols = _columns(width, latlon)
    for col, justify in cols:
        table.add_column(col, justify=justify, no_wrap=True)
    rows, hidden = order_rows(state, max_rows)
    legs = planned_legs(state.plan)
    for v in rows:
        table.add_row(*_cells(state, v, cols, legs))
    parts: list[Any] = [_header(state)]
    parts += [Text(line, style="dim" if line.startswith("bus: connected") else "yellow", overflow="ellipsis",
                   no_wrap=True) for line in status]
    parts.append(table)
    if hidden:
        parts.append(Text(f"… {hidden} more", style="dim"))
    parts.append(Text("events", style="bold"))
    parts.append(_events(state, events))
    return Group(*parts)


def fit(state: FleetState, height: int, status_lines: int) -> tuple[int, int]:
    """(vehicle rows, event lines) that fit a terminal ``height`` lines high."""
    fixed = HEADER_LINES + bool(state.link_line) + bool(state.replans) + status_lines + 1 + 1 + 1
    free = max(height - fixed, 4)  # table header, "events" title, the last newline above
    events = min(MAX_EVENTS, max(2, free // 4))
    return max(free - events, 2), events


PLAIN_WIDTH = 4000  # characters: "no terminal" output is laid out this wide, so that no cell is cut


def plain_text(renderable: Any, width: int | None = None) -> str:
    """``renderable`` as plain text ``width`` wide; None = uncut lines (as wide as their content:
    for output without a terminal, where nobody's screen width applies)."""
    console = Console(width=width or PLAIN_WIDTH, record=True, file=io.StringIO(), color_system=None)
    console.print(renderable)
    text = console.export_text()
    return text if width else "".join(line.rstrip() + "\n" for line in text.splitlines())


def render_text(state: FleetState, width: int | None = None, latlon: bool = False) -> str:
    """The whole dashboard of ``state`` as plain text (``--headless`` endings, tests): ``width``
    wide, or without a width in uncut lines (:func:`plain_text`)."""
    return plain_text(render(state, None, latlon=latlon, width=width), width)


class LiveView(View):
    """Redraws the dashboard at :data:`REFRESH_HZ` from a task on the running loop."""

    def __init__(self, console: Console | None = None, latlon: bool = False) -> None:
        self.console = console or Console()
        self.latlon = latlon
        self._live: Live | None = None
        self._task: asyncio.Task[None] | None = None
        self._state: FleetState | None = None
        self._status: list[Callable[[], str]] = []

    def add_status(self, line: Callable[[], str]) -> None:
        """Show ``line()`` under the header on every redraw (the MQTT bus status)."""
        self._status.append(line)

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        self._state = state
        if self._live is None:
            self._live = Live(console=self.console, auto_refresh=False, transient=False,
                              redirect_stdout=False, redirect_stderr=False)
            self._live.start()
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._loop(), name="dashboard")

    async def _loop(self) -> None:
        while True:
            self._draw()
            await asyncio.sleep(1.0 / REFRESH_HZ)

    def _draw(self) -> None:
        if self._live is None or self._state is None:
            return
        self._live.update(self.renderable(), refresh=True)

    def renderable(self) -> Group:
        """The dashboard sized to the console (the vehicle rows and events that fit)."""
        assert self._state is not None
        status = [f() for f in self._status]
        size = self.console.size
        rows, events = fit(self._state, size.height, len(status))
        return render(self._state, rows, status, latlon=self.latlon, width=size.width, events=events)

    async def stop(self) -> None:
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._draw()
        if self._live is not None:
            self._live.stop()
            self._live = None


class HeadlessView(View):
    """One line per event on ``out`` (stdout by default); ``prefix`` goes before the event kind
    (a run of several teams: the team's carrier)."""

    def __init__(self, out: IO[str] | None = None, prefix: str = "") -> None:
        self.out = out or sys.stdout
        self.prefix = prefix
        self._unlisten: Any = None

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        if self._unlisten is None:
            for ev in list(state.events):  # what happened before the view started (e.g. the bus)
                self._print(ev)
            self._unlisten = state.add_listener(self._print)

    def _print(self, ev: Event) -> None:
        self.out.write(f"[{tplus(ev.mission_time):>10}] {self.prefix}{ev.kind:<16} {ev.text}\n")
        self.out.flush()

    async def stop(self) -> None:
        if self._unlisten is not None:
            self._unlisten()
            self._unlisten = None


def make_view(headless: bool | None = None, latlon: bool = False) -> View:
    """``--headless`` (or stdout not a terminal) → :class:`HeadlessView`, else :class:`LiveView`."""
    if headless is None:
        headless = not sys.stdout.isatty()
    return HeadlessView() if headless else LiveView(latlon=latlon)


__all__ = ["REFRESH_HZ", "HeadlessView", "LiveView", "fit", "make_view", "order_rows", "render",
           "plain_text", "render_text", "tplus"]
