"""The live web map in a real browser: short deployments on the embedded simulated fleet with
``--web``, their page opened in Debian's chromium through Playwright (no browser download): one
team on loopback (no token), two teams bound beyond loopback (every team drawn; the token).

Skipped only when chromium (or the playwright package) is missing here; scripts/test.sh installs
both, so CI runs it.
"""

from __future__ import annotations

import copy
import math
import os
import queue
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from views_helpers import TWO_TEAMS, mission_dict, write_mission

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]
REPO = Path(__file__).resolve().parents[2]
RUN_TIMEOUT = 180.0  # s: the whole deployment (a bound, not a measurement)
POLL = 0.1  # s between two looks at the page

pytestmark = [pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (scripts/test.sh "
                                "installs Debian's chromium; apt-get install -y chromium)"), pytest.mark.slow]

READ_VEHICLES = """() => [...document.querySelectorAll('[data-vehicle]')].map(e => ({
    id: e.dataset.vehicle, state: e.dataset.state, e: e.dataset.e, n: e.dataset.n}))"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _lines(proc: subprocess.Popen[str]) -> queue.Queue[str]:
    q: queue.Queue[str] = queue.Queue()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            q.put(line)
    threading.Thread(target=read, daemon=True).start()
    return q


def _wait_for_url(lines: queue.Queue[str], proc: subprocess.Popen[str]) -> str:
    deadline = time.monotonic() + 60.0
    seen: list[str] = []
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1.0)
        except queue.Empty:
            if proc.poll() is not None:
                break
            continue
        seen.append(line)
        if line.startswith("web map: "):
            return line.split(": ", 1)[1].strip()
    raise AssertionError("no 'web map:' line from fleetctl:\n" + "".join(seen))


def _watch_page(start: Any, user_dir: Path,
                read: str = READ_VEHICLES) -> tuple[list[Any], subprocess.Popen[str]]:
    """Start the browser, then the run (``start()`` -> (url, process)); what the page said
    (``read``: by default its vehicle elements), every POLL s until the run is over."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="the playwright package is not installed")
    looks: list[Any] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch_persistent_context(str(user_dir), executable_path=CHROMIUM, headless=True,
                                                       args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page()  # ready before the rovers leave the deck
            url, proc = start()
            page.goto(url, timeout=30_000)
            page.wait_for_selector("[data-vehicle]", timeout=30_000)
            deadline = time.monotonic() + RUN_TIMEOUT
            while proc.poll() is None and time.monotonic() < deadline:
                looks.append(page.evaluate(read))
                page.wait_for_timeout(POLL * 1000)
            looks.append(page.evaluate(read))  # the last frame stays on the page
        finally:
            browser.close()
    return looks, proc


def _history(looks: list[list[dict[str, Any]]], vid: str) -> list[dict[str, Any]]:
    return [v for look in looks for v in look if v["id"] == vid and v["e"] is not None]


def _changes(seq: list[str]) -> list[str]:
    return [s for k, s in enumerate(seq) if k == 0 or seq[k - 1] != s]


def _controller(command: str, mission: Path, tmp_path: Path, port: int,
                procs: list[subprocess.Popen[str]]) -> Callable[[], tuple[str, subprocess.Popen[str]]]:
    """Starts ``fleetctl COMMAND`` with the web map on ``port`` (kept in ``procs``) and returns the
    map's URL once printed, and the process."""
    def start() -> tuple[str, subprocess.Popen[str]]:
        proc = subprocess.Popen(
            [sys.executable, "-m", "fleetctl.cli", command, "--mission", str(mission), "--headless",
             "--run-dir", str(tmp_path / "run"), "--web", f"127.0.0.1:{port}"],
            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        procs.append(proc)
        return _wait_for_url(_lines(proc), proc), proc
    return start


def _watch_controller(command: str, mission: Path, tmp_path: Path, *read: str) -> list[Any]:
    """``fleetctl COMMAND`` with the web map, watched in the browser (``read``: the page script,
    :func:`_watch_page`) until it exits 0; what the page showed, look by look."""
    procs: list[subprocess.Popen[str]] = []
    try:
        looks, proc = _watch_page(_controller(command, mission, tmp_path, _free_port(), procs),
                                  tmp_path / "chromium-profile", *read)
        assert proc.wait(timeout=60) == 0
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)
    return looks


def test_deploy_shows_vehicles_moving_to_their_tasks(tmp_path: Path) -> None:
    d = mission_dict(rovers=2, speedup=2.0)
    mission = write_mission(d, tmp_path / "mission.yaml")
    looks = _watch_controller("deploy", mission, tmp_path)
    assert {v["id"] for v in looks[-1]} == {"carrier", "r1", "r2"}
    tasks = {t["id"]: t["position"] for t in d["tasks"]}
    for rid in ("r1", "r2"):
        hist = _history(looks, rid)
        states = _changes([v["state"] for v in hist])
        assert "on_deck" in states and states[-1] == "on_task", states
        flying = [k for k, s in enumerate(states) if s in ("climbing", "en_route")]
        assert flying and states.index("on_deck") < flying[0], states  # deck, then in the air on its way
        positions = {(v["e"], v["n"]) for v in hist}
        assert len(positions) > 2  # it moved on the page
        last = hist[-1]
        task = next(tasks[t] for t in tasks if math.hypot(float(last["e"]) - tasks[t][0],
                                                          float(last["n"]) - tasks[t][1]) < 2.0)
        assert task in tasks.values()  # it ended at a task (within 2 m, the controller's reach is 1 m 3D)
    ends = {min(tasks, key=lambda t: math.hypot(float(_history(looks, r)[-1]["e"]) - tasks[t][0],
                                                float(_history(looks, r)[-1]["n"]) - tasks[t][1]))
            for r in ("r1", "r2")}
    assert ends == {"t1", "t2"}  # each at its own task
    carrier = _changes([v["state"] for v in _history(looks, "carrier")])
    assert "driving" in carrier and "holding" in carrier


# -- a long operation: each task's work on its marker, the sorties out -------------------------------

READ_OPERATION = """() => ({
    tasks: [...document.querySelectorAll('#tasks [data-task]')].map(g => {
        const bar = g.querySelector('.work-done'), bg = g.querySelector('.work-bg');
        return {id: g.dataset.task, worked: g.dataset.worked, duration: g.dataset.duration,
                progress: g.dataset.progress, rover: g.dataset.rover, done: g.classList.contains('done'),
                working: g.classList.contains('working'),
                bar: bar ? Number(bar.getAttribute('width')) / Number(bg.getAttribute('width')) : null};
    }),
    sorties: [...document.querySelectorAll('#sorties [data-sortie]')].map(s => ({
        sortie: s.dataset.sortie, rover: s.dataset.rover, tasks: s.dataset.tasks,
        planned: s.classList.contains('planned'), takeoff_in: s.dataset.in,
        points: s.getAttribute('points').trim().split(/\\s+/).filter(Boolean).length}))})"""


def test_an_operation_shows_each_task_s_work_and_the_sorties_out(tmp_path: Path) -> None:
    from tests.run.operation.ops_helpers import small_operation

    d = small_operation()
    mission = write_mission(d, tmp_path / "mission.yaml")
    durations = {t["id"]: float(t["duration"]) for t in d["tasks"]}
    looks = _watch_controller("run", mission, tmp_path, READ_OPERATION)
    marks = [t for look in looks for t in look["tasks"] if t["progress"] is not None]
    working = [t for t in marks if t["working"]]
    assert working, "no task marker ever showed work in progress"
    for t in working:  # work done / duration on the marker: its text, its bar, the rover at it
        # 1.000 while working: the duration has been worked and the rover's "done" is on its way
        assert 0.0 < float(t["progress"]) <= 1.0 and t["rover"] in ("r1", "r2"), t
        assert float(t["duration"]) == durations[t["id"]], t
        assert t["bar"] == pytest.approx(float(t["progress"]), abs=0.01), t
    assert any(float(t["progress"]) < 1.0 for t in working), working  # seen part-way, not only at the end
    sorties = [s for look in looks for s in look["sorties"] if not s["planned"]]
    assert {s["rover"] for s in sorties} == {"r1", "r2"}  # every rover's sortie drawn while out
    assert any(s["tasks"] and s["points"] >= 2 for s in sorties), sorties  # rover -> its tasks left
    # a sortie drawn ahead of its launch (launch stop -> its tasks -> pick-up stop), then drawn out
    seen = [(i, s) for i, look in enumerate(looks) for s in look["sorties"]]
    ahead = [(i, s) for i, s in seen if s["planned"] and float(s["takeoff_in"]) >= 0.0
             and s["points"] == len(s["tasks"].split()) + 2]
    assert any(j > i and o["sortie"] == a["sortie"] and not o["planned"]
               for i, a in ahead for j, o in seen), seen
    last = looks[-1]
    assert sorted(t["id"] for t in last["tasks"]) == sorted(durations) and not last["sorties"]
    for t in last["tasks"]:  # the end: every task done, its whole duration worked
        assert t["done"] and t["progress"] == "1.000" and float(t["worked"]) == durations[t["id"]], t


# -- two teams, bound beyond loopback: every team drawn, and the token ------------------------------

READ_TEAMS = """() => {
    const colour = (e, prop) => e ? getComputedStyle(e)[prop] : null;
    const teams = {};
    for (const s of document.querySelectorAll('#teams [data-team]')) teams[s.dataset.team] = {
        eta: s.dataset.eta, text: s.textContent, colour: colour(s, 'color')};
    const routes = {};
    for (const r of document.querySelectorAll('[data-route]')) routes[r.dataset.route] = {
        points: r.getAttribute('points').trim().split(/\\s+/).length, colour: colour(r, 'stroke')};
    const carriers = {};
    for (const c of document.querySelectorAll('.vehicle.carrier')) carriers[c.dataset.vehicle] = {
        team: c.dataset.team, colour: colour(c.querySelector('.body'), 'fill')};
    return {teams, routes, carriers};
}"""


def _status(url: str, headers: dict[str, str] | None = None) -> int:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, headers=headers or {}), timeout=10) as r:
            return int(r.status)
    except urllib.error.HTTPError as e:
        return int(e.code)


def test_two_teams_are_drawn_and_beyond_loopback_the_map_needs_its_token(tmp_path: Path) -> None:
    mission = write_mission(copy.deepcopy(TWO_TEAMS), tmp_path / "mission.yaml")
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if k != "FLEETCTL_WEB_TOKEN"}  # a token made at start
    sync_api = pytest.importorskip("playwright.sync_api", reason="the playwright package is not installed")
    proc = subprocess.Popen(
        [sys.executable, "-m", "fleetctl.cli", "deploy", "--mission", str(mission), "--headless",
         "--run-dir", str(tmp_path / "run"), "--web", f"0.0.0.0:{port}"],
        cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    looks: list[dict[str, Any]] = []
    try:
        printed = _wait_for_url(_lines(proc), proc).split()[0]  # "LINK (the token is required: ...)"
        assert printed.startswith(f"http://0.0.0.0:{port}/?token=")
        token = printed.split("?token=", 1)[1]
        base = f"http://127.0.0.1:{port}/"
        for route in ("", "events", "state"):  # no token, a wrong one: nothing of the map
            assert _status(base + route) == 401, route
            assert _status(base + route + "?token=" + token[::-1]) == 403, route
            assert _status(base + route, {"Authorization": "Bearer " + token[:-2]}) == 403, route
        with sync_api.sync_playwright() as p:
            browser = p.chromium.launch_persistent_context(
                str(tmp_path / "profile"), executable_path=CHROMIUM, headless=True, args=CHROMIUM_FLAGS)
            try:
                page = browser.new_page()
                refused = page.goto(base, timeout=30_000)
                assert refused is not None and refused.status == 401  # the browser without the link
                opened = page.goto(f"{base}?token={token}", timeout=30_000)
                assert opened is not None and opened.status == 200  # the printed link opens the page
                page.wait_for_selector("#teams [data-team]", timeout=60_000)
                deadline = time.monotonic() + RUN_TIMEOUT
                while proc.poll() is None and time.monotonic() < deadline:
                    looks.append(page.evaluate(READ_TEAMS))
                    page.wait_for_timeout(POLL * 1000)
                looks.append(page.evaluate(READ_TEAMS))
                assert page.evaluate("document.getElementById('link').textContent") != "connecting…"
            finally:
                browser.close()
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    last = looks[-1]
    assert sorted(last["teams"]) == ["c1", "c2"]
    c1, c2 = last["teams"]["c1"]["colour"], last["teams"]["c2"]["colour"]
    assert c1 != c2
    for cid, colour in (("c1", c1), ("c2", c2)):  # each team's route and carrier in the team's colour
        assert last["routes"][cid]["points"] >= 2 and last["routes"][cid]["colour"] == colour
        assert last["carriers"][cid] == {"team": cid, "colour": colour}
    both = [look for look in looks if sorted(look["teams"]) == ["c1", "c2"]
            and all(t["eta"] and "ETA T+" in t["text"] for t in look["teams"].values())]
    assert both, [look["teams"] for look in looks]  # both teams' ETAs on the page at once while flying
