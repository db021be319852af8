"""Every team in the views: the terminal view and the web map of a run of several teams (states
built by hand from missions/two_carriers.yaml), and how a run's teams reach them."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from rich.console import Console
from views_helpers import FakeClock, deploy_plan

from fleetctl.mission import load_mission
from fleetctl.mission.teams import team_mission
from fleetctl.run.state import FleetState
from fleetctl.run.teams.views import team_views
from fleetctl.views.dashboard import HeadlessView, LiveView
from fleetctl.views.map_model import teams_frame, teams_plan
from fleetctl.views.teams import TEAM_COLOURS, ShownTeams
from fleetctl.views.view import Views
from fleetctl.views.web import WebMapView

MISSION = Path(__file__).resolve().parents[2] / "missions" / "two_carriers.yaml"
SHARES = {"c1": (["t1", "t3"], 0.0, 40.0), "c2": (["t12", "t10"], 200.0, 55.0)}  # tasks, start E, makespan


def _team_state(cid: str, clock: FakeClock) -> FleetState:
    m = load_mission(MISSION)
    tasks, e0, makespan = SHARES[cid]
    st = FleetState(team_mission(m, cid, tasks=tasks))
    st.mission_clock = clock
    rovers = [u.id for u in team_mission(m, cid).rovers.units][:2]
    where = {t.id: list(t.position) for t in m.tasks}
    legs = [(r, t, [e0, 50.0, 0.0], where[t], makespan - 5.0) for r, t in zip(rovers, tasks, strict=True)]
    plan = deploy_plan(legs, makespan, stop=[e0, 50.0, 0.0])
    plan["carrier"]["start"] = [e0, 0.0, 0.0]
    st.set_phase("deploy", makespan, 1)
    st.set_plan(plan, started=clock.t)
    st.stop_index = 1
    st.vehicles[cid].state, st.vehicles[cid].enu = "driving", (e0, 20.0, 0.0)
    for r in rovers:
        st.vehicles[r].state, st.vehicles[r].enu = "on_deck", (e0, 20.0, 0.3)
    st.event("stop_reached", f"{cid}: on its way to stop 1/1", cid)
    return st


def _two_teams(view: Any, clock: FakeClock) -> dict[str, FleetState]:
    """The two teams' states handed to ``view`` as a run of several teams does (its ports)."""
    ports = team_views(view, ["c1", "c2"])
    states = {cid: _team_state(cid, clock) for cid in ("c1", "c2")}
    for cid in ("c2", "c1"):  # in any order: the mission's order holds
        port = ports[cid]
        assert port is not None
        port.start(states[cid], None)
    return states


def test_the_map_documents_hold_every_team_in_its_colour() -> None:
    clock = FakeClock(10.0)
    web = WebMapView("127.0.0.1", 0)
    web.teams.declare(["c1", "c2"])
    states = {cid: _team_state(cid, clock) for cid in ("c1", "c2")}
    for cid, st in states.items():
        web.teams.set_team(cid, st)
    clock.t = 20.0
    hello = web.hello()
    layers = {x["team"]: x for x in hello["plan"]["teams"]}
    assert list(layers) == ["c1", "c2"]
    assert (layers["c1"]["colour"], layers["c2"]["colour"]) == TEAM_COLOURS[:2]
    assert layers["c1"]["route"] == [[0.0, 0.0], [0.0, 50.0]] and layers["c2"]["route"] == [[200.0, 0.0],
                                                                                           [200.0, 50.0]]
    assert {t["id"]: t["team"] for t in hello["plan"]["tasks"]} == {"t1": "c1", "t3": "c1", "t10": "c2",
                                                                     "t12": "c2"}
    f = hello["frame"]
    teams = {t["team"]: t for t in f["teams"]}
    assert teams["c1"]["eta"] == 40.0 and teams["c2"]["eta"] == 55.0  # each team's own ETA (T+)
    assert teams["c1"]["ttg"] == 30.0 and f["ttg"] == 45.0  # the run: the later team's
    carriers = {v["id"]: v["team"] for v in f["vehicles"] if v["role"] == "carrier"}
    assert carriers == {"c1": "c1", "c2": "c2"}
    assert {v["team"] for v in f["vehicles"] if v["role"] == "rover"} == {"c1", "c2"}
    assert {e["team"] for e in f["events"]} == {"c1", "c2"}


def test_a_rover_in_two_teams_states_is_shown_once_with_the_latest() -> None:
    clock = FakeClock(0.0)
    teams = ShownTeams()
    c1, c2 = _team_state("c1", clock), _team_state("c2", clock)
    teams.set_team("c1", c1)
    teams.set_team("c2", c2)
    later = FleetState(team_mission(load_mission(MISSION), "c2", tasks=(), rovers=["r1", "r9"]))
    teams.set_team("c2", later)  # c2's collection lands r1 (of c1's deck)
    owners = [(t.team, v.id) for t, v in teams.vehicles()]
    assert ("c2", "r1") in owners and ("c1", "r1") not in owners
    assert len(owners) == len({vid for _, vid in owners})
    doc = teams_frame(teams)
    assert sum(1 for v in doc["vehicles"] if v["id"] == "r1") == 1
    assert [x["team"] for x in teams_plan(teams)["teams"]] == ["c1", "c2"]


def test_the_terminal_view_shows_every_team() -> None:
    clock = FakeClock(10.0)
    console = Console(width=120, height=40, record=True, file=io.StringIO(), color_system=None)
    live = LiveView(console=console)
    live.declare_teams(["c1", "c2"])
    states = {cid: _team_state(cid, clock) for cid in ("c1", "c2")}
    for cid, st in states.items():
        live.teams.set_team(cid, st)  # what start_team keeps (drawn once here, without the redraw task)
    live._state = states["c1"]
    clock.t = 20.0
    console.print(live.renderable())
    lines = console.export_text().splitlines()
    head = [ln for ln in lines if ln.startswith("■ ")]
    assert len(head) == 2
    assert head[0].split()[1:4] == ["c1", "deploy", "stop"] and "ETA T+40.0s" in head[0]
    assert head[1].split()[1] == "c2" and "ETA T+55.0s" in head[1]
    assert "to go 45.0 s" in lines[0]  # the run's: the later team's
    rows = {ln.split()[1]: ln.split()[0] for ln in lines if ln.split() and ln.split()[0] in ("c1", "c2")}
    assert rows["c1"] == "c1" and rows["c2"] == "c2" and rows["r1"] == "c1" and rows["r9"] == "c2"
    events = lines[lines.index("events") + 1:]
    for cid in ("c1", "c2"):
        assert any(f" {cid} {cid}: on its way" in ln for ln in events)


def test_a_one_team_view_is_given_every_team_its_ports_say() -> None:
    """The ports of team_views: headless prints every team's events prefixed; the other views get
    every team's state (not only the first team's)."""
    out = io.StringIO()
    seen: list[tuple[str, FleetState]] = []

    class Spy(WebMapView):
        def start_team(self, team: str, state: FleetState, fleet: Any) -> None:
            seen.append((team, state))

    spy = Spy("127.0.0.1", 0)
    states = _two_teams(Views(HeadlessView(out), spy), FakeClock(0.0))
    assert seen == [("c2", states["c2"]), ("c1", states["c1"])]
    assert spy.teams.order == ["c1", "c2"]
    text = out.getvalue()
    assert "c1 stop_reached" in text and "c2 stop_reached" in text


def test_a_view_of_one_state_shows_the_first_team() -> None:
    """A view that draws one state (View's default start_team) is given the first team's."""
    from fleetctl.views.view import View

    class One(View):
        def __init__(self) -> None:
            self.started: list[FleetState] = []

        def start(self, state: FleetState, fleet: Any) -> None:
            self.started.append(state)

    one = One()
    states = _two_teams(one, FakeClock(0.0))  # c2's port starts first
    assert one.started == [states["c2"]]
    again = _team_state("c2", FakeClock(0.0))
    one.start_team("c2", again, None)  # the same team's next phase
    one.start_team("c1", states["c1"], None)
    assert one.started == [states["c2"], again]
