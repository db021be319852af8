"""The terminal view: what fits at 80x24, time to go, the one time base, colours, lat/lon."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console
from rich.table import Table
from rich.text import Text
from views_helpers import FakeClock, deploy_plan, mission, state_of

from fleetctl.run.state import FleetState
from fleetctl.views.dashboard import LiveView, render, render_text
from fleetctl.views.eta import carrier_time_to_go, mission_time_to_go, rover_time_to_go
from fleetctl.views.levels import battery_level

ROVERS = 18


def _fleet(tmp_path: Path) -> tuple[FleetState, FakeClock]:
    """18 rovers: r1-r10 on the deck, r11-r14 holding on their tasks, r15-r18 flying."""
    clock = FakeClock(100.0)
    st = state_of(mission(tmp_path, rovers=ROVERS), clock)
    st.vehicles["carrier"].state, st.vehicles["carrier"].enu = "driving", (5.0, 5.0, 0.0)
    for k in range(1, ROVERS + 1):
        v = st.vehicles[f"r{k}"]
        if k <= 10:
            v.state, v.enu, v.alt, v.on_ground = "on_deck", (5.0, 5.0, 0.2), 0.0, True
        elif k <= 14:
            v.state, v.enu, v.alt, v.on_ground = "on_task", (20.0, 10.0, 5.0), 5.0, False
        else:
            v.state, v.enu, v.alt, v.on_ground = "en_route", (10.0, 8.0, 4.0), 4.0, False
        v.battery_pct = 80.0
    return st, clock


def _screen(st: FleetState, width: int = 80, height: int = 24) -> list[str]:
    console = Console(width=width, height=height, record=True, file=io.StringIO(), color_system=None)
    view = LiveView(console=console)
    view._state = st  # drawn once, without starting the redraw task
    console.print(view.renderable())
    return console.export_text().splitlines()


def _ids(lines: list[str]) -> list[str]:
    return [ln.split()[0] for ln in lines if ln.split() and (ln.startswith("r") or ln.startswith("carrier"))
            and not ln.startswith("replans")]


def test_at_80x24_airborne_rovers_come_first_and_the_rest_is_counted(tmp_path: Path) -> None:
    st, _ = _fleet(tmp_path)
    for k in range(10):
        st.event("stop_reached", f"event {k}")
    lines = _screen(st)
    assert len(lines) <= 24 and max(len(x) for x in lines) <= 80
    ids = _ids(lines)
    flying, holding = [f"r{k}" for k in range(15, 19)], [f"r{k}" for k in range(11, 15)]
    assert ids[0] == "carrier"
    assert ids[1:5] == flying  # moving first, then the ones holding on their tasks, then the deck
    assert ids[5:9] == holding[: len(ids) - 5]
    more = [ln for ln in lines if ln.startswith("… ")]
    assert more == [f"… {ROVERS + 1 - len(ids)} more"]
    table_end = max(i for i, ln in enumerate(lines) if ln.split() and ln.split()[0] in ids)
    assert lines.index(more[0]) == table_end + 1  # the last line of the table part


def test_everything_that_fits_keeps_the_mission_order(tmp_path: Path) -> None:
    st, _ = _fleet(tmp_path)
    lines = _screen(st, width=120, height=60)
    assert _ids(lines) == ["carrier"] + [f"r{k}" for k in range(1, ROVERS + 1)]
    assert not [ln for ln in lines if ln.startswith("… ")]


def test_time_to_go_per_rover_and_for_the_mission(tmp_path: Path) -> None:
    st, clock = _fleet(tmp_path)
    st.phase = "deploy"
    # r1 waits on the deck (planned arrival 50 s into the plan); r15 flies 10 m at 2 m/s to its task
    st.set_plan(deploy_plan([("r1", "t1", [5, 5, 0], [20, 10, 5], 50.0),
                             ("r15", "t2", [0, 8, 4], [20, 8, 4], 12.0)], makespan=50.0), started=80.0)
    clock.t = 100.0  # 20 s into the plan
    assert rover_time_to_go(st, st.vehicles["r1"]) == pytest.approx(30.0)  # by the plan
    assert rover_time_to_go(st, st.vehicles["r15"]) == pytest.approx(10.0 / 2.0)  # time model, its path left
    assert rover_time_to_go(st, st.vehicles["r11"]) is None  # not in the plan
    assert mission_time_to_go(st) == pytest.approx(30.0)
    st.stop_index = 1  # the carrier drives to stop 1, planned at 0 s of the plan: already due
    assert carrier_time_to_go(st) == pytest.approx(0.0)
    st.plan["stops"][0]["arrive"] = 26.0  # type: ignore[index]
    assert carrier_time_to_go(st) == pytest.approx(6.0)
    st.vehicles["carrier"].state = "holding"
    assert carrier_time_to_go(st) is None
    st.vehicles["r1"].state = "on_task"
    clock.t = 140.0  # the plan's makespan is over: the flying rover is what is left
    assert mission_time_to_go(st) == pytest.approx(5.0)
    text = render_text(st, width=160)
    assert "to go 5.0 s" in text
    st.set_phase("dwell", 60.0)  # run: the dwell's time left
    clock.t += 45.0
    assert mission_time_to_go(st) == pytest.approx(15.0)


def test_one_time_base_mission_seconds_in_header_and_events(tmp_path: Path) -> None:
    st, clock = _fleet(tmp_path)
    clock.t = 100.0
    st.mission_clock = clock  # T+ starts at 0 here
    clock.t = 112.3  # 12.3 mission seconds later, whatever the wall clock did
    st.event("stop_reached", "carrier: stop 1/2 reached", "carrier")
    clock.t = 130.0
    text = render_text(st)
    assert "T+30.0s" in text  # header
    assert "T+12.3s  carrier: stop 1/2 reached" in text
    assert st.events[-1].mission_time == pytest.approx(12.3, abs=1e-3)  # T+ carries on across a new clock


def _column(group: object, title: str) -> list[Text]:
    tables = [r for r in group.renderables if isinstance(r, Table)]  # type: ignore[attr-defined]
    col = next(c for t in tables for c in t.columns if c.header == title)
    return list(col.cells)  # type: ignore[arg-type]


def test_battery_and_link_colours(tmp_path: Path) -> None:
    st, _ = _fleet(tmp_path)  # reserve 0.1: red below 10 %, yellow below 20 %
    for k, pct in ((1, 9.0), (2, 15.0), (3, 20.0)):
        st.vehicles[f"r{k}"].battery_pct = pct
    st.vehicles["r4"].lost = True
    st.vehicles["r5"].link_age = 0.4
    assert [battery_level(st, st.vehicles[f"r{k}"]) for k in (1, 2, 3)] == ["reserve", "low", "ok"]
    group = render(st, None, width=120)
    batt = _column(group, "batt%")
    assert [batt[k].style for k in (1, 2, 3)] == ["bold red", "yellow", ""]
    link = _column(group, "link")
    assert (str(link[4]), link[4].style) == ("LOST", "bold red")
    assert (str(link[5]), link[5].style) == ("0.4", "")


def test_latlon_on_request(tmp_path: Path) -> None:
    st, _ = _fleet(tmp_path)
    st.vehicles["r1"].latlon = (47.3977421, 8.5455941)
    plain = render_text(st)
    assert "E m" in plain and "lat" not in plain.split("\n")[4]
    text = render_text(st, latlon=True)
    assert "47.397742" in text and "8.545594" in text and "E m" not in text


def test_without_a_width_the_text_is_plain_uncut_lines(tmp_path: Path) -> None:
    """``--headless`` / no terminal: no cell or line is cut to a screen width."""
    st, _ = _fleet(tmp_path)
    st.replans, st.last_replan = 1, "r15 lost: " + "its task goes to a spare on the deck " * 8
    long_event = "carrier: " + "a long event line that a screen would wrap " * 6
    st.event("stop_reached", long_event, "carrier")
    text = render_text(st)
    assert "…" not in text
    assert st.last_replan.strip() in text and long_event.strip() in text  # each on one line
    assert all(line == line.rstrip() for line in text.splitlines())
    assert "en_route" in text and "on_deck" in text
    assert long_event.strip() not in render_text(st, width=80)  # a given width still folds, as on a terminal


def test_a_long_operation_shows_its_sorties_task_progress_and_eta(tmp_path: Path) -> None:
    from fleetctl.run.state import OperationProgress, SortieAhead, SortieShown
    from fleetctl.views.map_model import frame

    st, _clock = _fleet(tmp_path)
    st.set_phase("operation", 600.0, 12)
    work = {"t1": (90.0, 90.0, "r1", True), "t2": (40.0, 120.0, "r2", False), "t3": (0.0, 60.0, None, False),
            "t4": (0.0, 30.0, None, False)}
    progress = OperationProgress(2, 3, 9, work, 640.5,
                                 (SortieShown(4, "r2", "flying", ("t2", "t3")),),
                                 (SortieAhead(5, "r1", ("t4",), (10.0, 5.0), (20.0, 5.0), 12.34),))
    st.operation = lambda: progress
    text = render_text(st, width=160)
    assert "sorties 2 out, 3 back of 9 · tasks 1/4 done · ETA 640.5 s" in text
    assert "next: r1 in 12 s (t4)" in text  # the next sortie to take off
    assert "working: t2 40/120 s (r2)" in text and "t3" not in text.split("working:")[1]
    assert st.snapshot()["operation"]["eta"] == 640.5
    op = frame(st)["operation"]  # the web map's document
    assert op["working"] == ["t2"] and op["tasks"]["t2"] == [40.0, 120.0, "r2", False] and op["done"] == 1
    assert op["tasks"]["t1"] == [90.0, 90.0, "r1", True]
    assert op["out"] == [{"sortie": 4, "rover": "r2", "status": "flying", "tasks": ["t2", "t3"]}]
    assert op["ahead"] == [{"sortie": 5, "rover": "r1", "tasks": ["t4"], "launch": [10.0, 5.0],
                            "pickup": [20.0, 5.0], "in": 12.3}]
    assert op["eta"] == pytest.approx(st.mission_time - st.elapsed + 640.5, abs=0.1)
