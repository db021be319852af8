"""The operator's view of a run: a live terminal dashboard (rich) or, ``--headless``, one log
line per event.

:class:`LiveView` redraws from :class:`fleetctl.run.state.FleetState` a few times a second in a
task of its own (``rich.live.Live`` without its refresh thread), so the view never blocks the
mission; :class:`HeadlessView` prints each event as it happens. :func:`make_view` picks one.
"""

from __future__ import annotations

import asyncio
import io
import sys
from collections.abc import Callable, Sequence
from typing import IO, TYPE_CHECKING

from rich.console import Console, Group, JustifyMethod, RenderableType
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from fleetctl.aio import cancel_and_wait
from fleetctl.run.kinds import Ev
from fleetctl.run.state import Event, FleetState, OperationProgress, VehicleState
from fleetctl.views.eta import FLYING, PlannedLeg, mission_time_to_go, planned_legs, time_to_go
from fleetctl.views.levels import STYLE, battery_level, link_level
from fleetctl.views.teams import ShownTeam, ShownTeams
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
    bar = ProgressBar(total=max(planned or 1.0, 1e-6), completed=min(elapsed, planned or 0.0), width=24)
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


def _operation_line(op: OperationProgress, working: int = 4) -> Text:
    """A long operation: sorties out and back, tasks done, the ETA, the tasks being worked with
    their work done / duration (at most ``working`` of them) and the next sortie to take off."""
    eta = "" if op.eta is None else f" · ETA {op.eta:.1f} s"
    line = (f"sorties {op.sorties_out} out, {op.sorties_back} back of {op.sorties_planned} · "
            f"tasks {op.done}/{len(op.tasks)} done{eta}")
    now = op.working()
    if now:
        shown = ", ".join(f"{t} {w:.0f}/{d:.0f} s ({r})" for t, w, d, r in now[:working])
        line += f" · working: {shown}" + (f" … {len(now) - working} more" if len(now) > working else "")
    if op.ahead:
        a = op.ahead[0]
        line += f" · next: {a.rover} in {a.takeoff_in:.0f} s ({', '.join(a.tasks)})"
    return Text(line, style="cyan", overflow="ellipsis", no_wrap=True)


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
           legs: dict[str, PlannedLeg]) -> list[RenderableType]:
    st = "lost" if v.lost else v.state
    batt = STYLE.get(battery_level(state, v), "")
    link = link_level(v)
    ttg = time_to_go(state, v, legs)
    ll = v.latlon
    values: dict[str, RenderableType] = {
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
    parts: list[RenderableType] = [_header(state)]
    if state.operation is not None:
        parts.append(_operation_line(state.operation()))
    parts += [Text(line, style="dim" if line.startswith("bus: connected") else "yellow", overflow="ellipsis",
                   no_wrap=True) for line in status]
    parts.append(table)
    if hidden:
        parts.append(Text(f"… {hidden} more", style="dim"))
    parts.append(Text("events", style="bold"))
    parts.append(_events(state, events))
    return Group(*parts)


def _team_rows(teams: ShownTeams) -> Table:
    """One line per team: the team in its colour, phase, stop k of N, elapsed vs planned, ETA,
    time to go and a progress bar."""
    grid = Table.grid(padding=(0, 2))
    for _ in range(6):
        grid.add_column(no_wrap=True)
    for t in teams.shown():
        st = t.state
        stop = f"stop {st.stop_index}/{st.stop_count}" if st.stop_count else ""
        times = f"{st.elapsed:.1f}" + (f" / {st.planned:.1f} s" if st.planned else " s")
        togo = mission_time_to_go(st)
        eta = "" if togo is None else f"ETA {tplus(st.mission_time + togo)}  to go {togo:.1f} s"
        planned = st.planned
        bar = ProgressBar(total=max(planned or 1.0, 1e-6), completed=min(st.elapsed, planned or 0.0),
                          width=16, complete_style=t.colour or "bar.complete")
        replans = f"replans {st.replans}" if st.replans else ""
        grid.add_row(Text(f"■ {t.team}", style=f"bold {t.colour}"), Text(str(st.phase)), Text(stop),
                     Text(times, style="dim"), Text(eta + (f"  {replans}" if replans else "")), bar)
    return grid


def _teams_header(teams: ShownTeams) -> Text:
    togo = [x for x in (mission_time_to_go(t.state) for t in teams.shown()) if x is not None]
    clock = tplus(teams.mission_time) + (f"  to go {max(togo):.1f} s" if togo else "")
    n = len(teams.shown())
    return Text.assemble((f"{teams.mission_name} · {n} teams", "bold"), "  ", clock)


def order_team_rows(teams: ShownTeams,
                    max_rows: int | None) -> tuple[list[tuple[ShownTeam, VehicleState]], int]:
    """Every team's vehicles (a team's carrier first), and how many are left out: as
    :func:`order_rows` over the vehicles of every team (carriers, then rovers in the air, then
    the rest; teams in order within each)."""
    rows = teams.vehicles()
    if max_rows is None or len(rows) <= max_rows:
        return rows, 0
    def rank(row: tuple[ShownTeam, VehicleState]) -> int:
        v = row[1]
        if v.role == "carrier":
            return 0
        if _is_airborne(v):
            return 1 if v.state in FLYING else 2
        return 3
    keep = max(max_rows - 1, 0)
    return sorted(rows, key=rank)[:keep], len(rows) - keep


def _team_events(teams: ShownTeams, count: int) -> Text:
    width = max((len(t.team or "") for t in teams.shown()), default=0)
    out = Text()
    for team, ev in teams.events(count):
        out.append(f"{tplus(ev.mission_time):>9}  ", style="dim")
        out.append(f"{(team.team if team else ''):<{width}} ", style=f"bold {team.colour}" if team else "")
        out.append(ev.text + "\n", style="red" if ev.kind in ALERT_KINDS else "")
    return out


def render_teams(teams: ShownTeams, max_rows: int | None = None, status: Sequence[str] = (), *,
                 latlon: bool = False, width: int | None = None, events: int = MAX_EVENTS) -> Group:
    """The dashboard of several teams: the mission's ``T+`` and time to go, one line per team (in
    its colour: phase, stop k of N, elapsed vs planned, ETA, time to go, progress), one table of
    every team's vehicles (the team column in its colour) and the latest events of every team."""
    if not teams.several:
        shown = teams.shown()
        state = shown[0].state if shown else None
        assert state is not None, "no state to draw"
        return render(state, max_rows, status, latlon=latlon, width=width, events=events)
    table = Table(expand=False, pad_edge=False, box=None, header_style="bold")
    cols = _columns(width, latlon)
    table.add_column("team", no_wrap=True)
    for col, justify in cols:
        table.add_column(col, justify=justify, no_wrap=True)
    rows, hidden = order_team_rows(teams, max_rows)
    legs = {t.team: planned_legs(t.state.plan) for t in teams.shown()}
    for team, v in rows:
        table.add_row(Text(team.team or "", style=f"bold {team.colour}"),
                      *_cells(team.state, v, cols, legs[team.team]))
    parts: list[RenderableType] = [_teams_header(teams), _team_rows(teams)]
    link = _teams_link(teams)
    if link is not None:
        parts.append(Text.assemble(("link ", "bold"), (link.link_line, link.link_style)))
    parts += [Text(line, style="dim" if line.startswith("bus: connected") else "yellow", overflow="ellipsis",
                   no_wrap=True) for line in status]
    parts.append(table)
    if hidden:
        parts.append(Text(f"… {hidden} more", style="dim"))
    parts.append(Text("events", style="bold"))
    parts.append(_team_events(teams, events))
    return Group(*parts)


def _teams_link(teams: ShownTeams) -> FleetState | None:
    """The state whose link line the view shows (the teams share one set of links): the first
    with something to say."""
    return next((t.state for t in teams.shown() if t.state.link_line), None)


def fit_teams(teams: ShownTeams, height: int, status_lines: int) -> tuple[int, int]:
    """(vehicle rows, event lines) of several teams that fit a terminal ``height`` lines high."""
    link = _teams_link(teams) is not None
    fixed = 1 + len(teams.shown()) + link + status_lines + 1 + 1 + 1
    free = max(height - fixed, 4)
    events = min(MAX_EVENTS, max(2, free // 4))
    return max(free - events, 2), events


def fit(state: FleetState, height: int, status_lines: int) -> tuple[int, int]:
    """(vehicle rows, event lines) that fit a terminal ``height`` lines high."""
    fixed = HEADER_LINES + bool(state.link_line) + bool(state.replans) + status_lines + 1 + 1 + 1
    free = max(height - fixed, 4)  # table header, "events" title, the last newline above
    events = min(MAX_EVENTS, max(2, free // 4))
    return max(free - events, 2), events


PLAIN_WIDTH = 4000  # characters: "no terminal" output is laid out this wide, so that no cell is cut


def plain_text(renderable: RenderableType, width: int | None = None) -> str:
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
        self.teams = ShownTeams()  # a run of several teams: every team's state
        self._status: list[Callable[[], str]] = []

    def add_status(self, line: Callable[[], str]) -> None:
        """Show ``line()`` under the header on every redraw (the MQTT bus status)."""
        self._status.append(line)

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        self._state = state
        self.teams.set_main(state)
        self._begin()

    def declare_teams(self, teams: Sequence[str], *, every: bool = False) -> None:
        self.teams.declare(teams, every=every)

    def start_team(self, team: str, state: FleetState, fleet: Fleet | None) -> None:
        """Draw ``team``'s state beside the other teams' (:func:`render_teams`)."""
        if self._state is None:
            self._state = state
        self.teams.set_team(team, state)
        self._begin()

    def _begin(self) -> None:
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
        if self.teams.several:
            rows, events = fit_teams(self.teams, size.height, len(status))
            return render_teams(self.teams, rows, status, latlon=self.latlon, width=size.width, events=events)
        rows, events = fit(self._state, size.height, len(status))
        return render(self._state, rows, status, latlon=self.latlon, width=size.width, events=events)

    async def stop(self) -> None:
        task, self._task = self._task, None
        await cancel_and_wait(task)
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
        self._unlisten: Callable[[], None] | None = None
        self._teams: dict[tuple[str, int], Callable[[], None]] = {}

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        if self._unlisten is None:
            for ev in list(state.events):  # what happened before the view started (e.g. the bus)
                self._print(ev)
            self._unlisten = state.add_listener(self._print)

    def _print(self, ev: Event, prefix: str | None = None) -> None:
        prefix = self.prefix if prefix is None else prefix
        self.out.write(f"[{tplus(ev.mission_time):>10}] {prefix}{ev.kind:<16} {ev.text}\n")
        self.out.flush()

    def start_team(self, team: str, state: FleetState, fleet: Fleet | None) -> None:
        """Print ``team``'s events too, each line prefixed with the team (``watch`` of several teams)."""
        key = (team, id(state))
        if key in self._teams:
            return
        prefix = f"{self.prefix}{team} "
        for ev in list(state.events):
            self._print(ev, prefix)
        self._teams[key] = state.add_listener(lambda ev: self._print(ev, prefix))

    async def stop(self) -> None:
        if self._unlisten is not None:
            self._unlisten()
            self._unlisten = None
        for unlisten in self._teams.values():
            unlisten()
        self._teams.clear()


def make_view(headless: bool | None = None, latlon: bool = False) -> View:
    """``--headless`` (or stdout not a terminal) → :class:`HeadlessView`, else :class:`LiveView`."""
    if headless is None:
        headless = not sys.stdout.isatty()
    return HeadlessView() if headless else LiveView(latlon=latlon)


__all__ = ["REFRESH_HZ", "HeadlessView", "LiveView", "fit", "fit_teams", "make_view", "order_rows",
           "order_team_rows", "plain_text", "render", "render_teams", "render_text", "tplus"]
