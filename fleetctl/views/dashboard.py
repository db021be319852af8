"""The operator's view of a run: a live terminal dashboard (rich) or, ``--headless``, one log
line per event.

:class:`LiveView` redraws from :class:`fleetctl.fleet.FleetState` a few times a second in a
task of its own (``rich.live.Live`` without its refresh thread), so the view never blocks the
mission; :class:`HeadlessView` prints each event as it happens. :func:`make_view` picks one.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from collections.abc import Callable, Sequence
from typing import IO, TYPE_CHECKING, Any

from rich.console import Console, Group, JustifyMethod
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from fleetctl.run.state import Event, FleetState
from fleetctl.views.view import View

if TYPE_CHECKING:
    from fleetctl.mavlink.fleet import Fleet

REFRESH_HZ = 4.0

_STATE_STYLE = {
    "on_deck": "cyan", "climbing": "yellow", "en_route": "yellow", "on_task": "green", "returning": "yellow",
    "landed": "magenta", "loaded": "green", "lost": "bold red", "refused": "red", "holding": "blue",
    "driving": "yellow", "idle": "dim",
}


def _num(v: float | None, fmt: str = "{:.1f}") -> str:
    return "–" if v is None else fmt.format(v)


def render(state: FleetState, max_rows: int | None = None, status: Sequence[str] = ()) -> Group:
    """The dashboard for ``state``: header (phase, stop k of N, planned vs elapsed with a progress
    bar), one row per vehicle, latest events; ``status`` lines (e.g. the MQTT bus) under the header."""
    elapsed = state.elapsed
    planned = state.planned
    head = Table.grid(padding=(0, 2))
    head.add_column()
    head.add_column()
    head.add_column()
    stop = f"stop {state.stop_index}/{state.stop_count}" if state.stop_count else ""
    timing = f"elapsed {elapsed:6.1f} s" + (f" / planned {planned:.1f} s" if planned else "")
    if state.eta is not None and planned and abs(state.eta - planned) >= 0.05:
        timing += f" · ETA {state.eta:.1f} s"
    bar: Any = ProgressBar(total=max(planned or 1.0, 1e-6), completed=min(elapsed, planned or 0.0), width=30)
    head.add_row(Text(f"{state.mission_name}  ·  {state.phase}", style="bold"), Text(stop), Text(timing))
    head.add_row("", "", bar)
    if state.link_line:
        head.add_row(Text("link", style="bold"), Text(state.link_line, style=state.link_style), "")
    if state.replans:
        head.add_row(Text(f"replans {state.replans}", style="bold magenta"),
                     Text(state.last_replan or "", style="magenta", overflow="ellipsis"), "")

    table = Table(expand=False, pad_edge=False, box=None, header_style="bold")
    columns: tuple[tuple[str, JustifyMethod], ...] = (
        ("id", "left"), ("role", "left"), ("state", "left"), ("task", "left"), ("E m", "right"),
        ("N m", "right"), ("alt m", "right"), ("m/s", "right"), ("batt%", "right"), ("range", "right"),
        ("link s", "right"))
    for col, justify in columns:
        table.add_column(col, justify=justify, no_wrap=True)
    rows = list(state.vehicles.values())
    hidden = 0
    if max_rows is not None and len(rows) > max_rows:
        hidden = len(rows) - max_rows
        rows = rows[:max_rows]
    for v in rows:
        st = "lost" if v.lost else v.state
        link = _num(v.link_age)
        table.add_row(
            v.id, v.role, Text(st, style=_STATE_STYLE.get(st, "")), v.task or "",
            _num(v.enu[0] if v.enu else None), _num(v.enu[1] if v.enu else None), _num(v.alt),
            _num(v.speed), _num(v.battery_pct, "{:.0f}"), _num(v.range_m, "{:.0f}"),
            Text(link, style="red" if v.link_age is not None and v.link_age > 2 else ""),
        )
    parts: list[Any] = [head]
    parts += [Text(line, style="dim" if line.startswith("bus: connected") else "yellow") for line in status]
    parts.append(table)
    if hidden:
        parts.append(Text(f"… {hidden} more vehicles", style="dim"))
    events = Text()
    for ev in list(state.events)[-8:]:
        events.append(f"{ev.elapsed:7.1f}s  ", style="dim")
        events.append(ev.text + "\n", style="red" if ev.kind in ("error", "rover_refused", "link_lost",
                                                                  "task_unserved", "rover_failed",
                                                                  "task_change_rejected") else "")
    parts.append(Text("events", style="bold"))
    parts.append(events)
    return Group(*parts)


class LiveView(View):
    """Redraws the dashboard at :data:`REFRESH_HZ` from a task on the running loop."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console()
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
        rows = max(self.console.size.height - 16, 5)
        self._live.update(render(self._state, rows, [f() for f in self._status]), refresh=True)

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
    """One line per event on ``out`` (stdout by default)."""

    def __init__(self, out: IO[str] | None = None) -> None:
        self.out = out or sys.stdout
        self._unlisten: Any = None

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        if self._unlisten is None:
            for ev in list(state.events):  # what happened before the view started (e.g. the bus)
                self._print(ev)
            self._unlisten = state.add_listener(self._print)

    def _print(self, ev: Event) -> None:
        self.out.write(f"[{ev.elapsed:8.2f}s] {ev.kind:<16} {ev.text}\n")
        self.out.flush()

    async def stop(self) -> None:
        if self._unlisten is not None:
            self._unlisten()
            self._unlisten = None


def make_view(headless: bool | None = None) -> View:
    """``--headless`` (or stdout not a terminal) → :class:`HeadlessView`, else :class:`LiveView`."""
    if headless is None:
        headless = not sys.stdout.isatty()
    return HeadlessView() if headless else LiveView()


__all__ = ["REFRESH_HZ", "HeadlessView", "LiveView", "make_view", "render"]
