"""The web map's server: bounded clients, slow clients dropped, shutdown closes everything."""

from __future__ import annotations

import asyncio
import io
import json
import math
import socket
from pathlib import Path

import aiohttp
import pytest
from views_helpers import FakeClock, deploy_plan, mission, state_of

from fleetctl.views.web import MapServer, WebError, WebMapView, parse_address, sse

TIMEOUT = 10.0  # s: every wait of these tests (none is a measurement)


async def _read_event(resp: aiohttp.ClientResponse) -> tuple[str, dict]:
    """The next server-sent event (keep-alive comments skipped)."""
    event, data = "", ""
    async with asyncio.timeout(TIMEOUT):
        while True:
            line = (await resp.content.readline()).decode()
            if line == "":
                raise EOFError("stream closed")
            if line.startswith("event: "):
                event = line[7:].strip()
            elif line.startswith("data: "):
                data += line[6:].strip()
            elif line == "\n" and event:
                return event, json.loads(data)


async def _eof(resp: aiohttp.ClientResponse) -> bool:
    async with asyncio.timeout(TIMEOUT):
        while True:
            if await resp.content.readline() == b"":
                return True


def _server(**kw: int) -> MapServer:
    return MapServer("127.0.0.1", 0, lambda: {"config": {}}, **kw)


def test_addresses() -> None:
    assert parse_address("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert parse_address("[::1]:9000") == ("::1", 9000)
    for bad in ("8080", "host:", ":80", "h:99999", "h:x"):
        with pytest.raises(WebError):
            parse_address(bad)


async def test_more_clients_than_allowed_are_refused() -> None:
    server = _server(max_clients=2)
    await server.start()
    try:
        async with aiohttp.ClientSession() as s:
            a = await s.get(server.url + "events")
            b = await s.get(server.url + "events")
            assert (await _read_event(a))[0] == "hello" and (await _read_event(b))[0] == "hello"
            c = await s.get(server.url + "events")
            assert c.status == 503 and server.refused == 1 and len(server.clients) == 2
            a.close()
            await asyncio.wait_for(_until(lambda: len(server.clients) == 1), TIMEOUT)
            d = await s.get(server.url + "events")  # a place is free again
            assert d.status == 200
            for r in (b, c, d):
                r.close()
    finally:
        await server.stop()


async def _until(cond: object) -> None:
    while not cond():  # type: ignore[operator]
        await asyncio.sleep(0.01)


async def test_a_client_that_cannot_keep_up_is_dropped() -> None:
    server = _server(queue_size=2)
    await server.start()
    try:
        async with aiohttp.ClientSession() as s:
            slow = await s.get(server.url + "events")
            await _read_event(slow)
            for k in range(3):  # no await in between: the client's handler cannot drain its queue
                server.broadcast(sse("frame", {"k": k}))
            assert server.dropped == 1 and not server.clients
            assert await _eof(slow)  # its stream ends; EventSource reconnects and gets hello again
    finally:
        await server.stop()


async def test_bind_failure_is_reported_not_raised(tmp_path: Path) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        st = state_of(mission(tmp_path), FakeClock())
        view = WebMapView("127.0.0.1", port)
        view.start(st, None)
        await asyncio.wait_for(view.ready.wait(), TIMEOUT)
        assert view.error is not None and "cannot listen" in view.error
        assert st.events[-1].kind == "web_failed"
        await view.stop()


async def test_the_view_streams_state_and_shutdown_cancels_its_tasks(tmp_path: Path) -> None:
    clock = FakeClock(0.0)
    st = state_of(mission(tmp_path), clock)
    st.set_plan(deploy_plan([("r1", "t1", [0, 0, 0], [20, 10, 5], 12.0)], 12.0), started=0.0)
    st.vehicles["r1"].enu, st.vehicles["r1"].state = (0.0, 0.0, 0.0), "on_deck"
    before = asyncio.all_tasks()
    urls: list[str] = []
    view = WebMapView("127.0.0.1", 0, hz=20.0, on_ready=urls.append)
    view.start(st, None)
    await asyncio.wait_for(view.ready.wait(), TIMEOUT)
    async with aiohttp.ClientSession() as s:
        stream = await s.get(urls[0] + "events")
        kind, hello = await _read_event(stream)
        assert kind == "hello" and hello["plan"]["tasks"][0]["id"] == "t1"
        assert {v["id"] for v in hello["frame"]["vehicles"]} == {"carrier", "r1", "r2"}
        st.vehicles["r1"].enu, st.vehicles["r1"].state = (10.0, 5.0, 3.0), "en_route"
        while True:
            kind, doc = await _read_event(stream)
            r1 = next((v for v in doc.get("vehicles", []) if v["id"] == "r1"), None)
            if kind == "frame" and r1 and r1["state"] == "en_route":
                break
        assert (r1["e"], r1["n"]) == (10.0, 5.0)
        page = await s.get(urls[0])
        assert page.status == 200 and "map.js" in await page.text()
        doc = await (await s.get(urls[0] + "state")).json()  # the hello document, for scripts
        r1_doc = next(v for v in doc["frame"]["vehicles"] if v["id"] == "r1")
        assert doc["plan"]["teams"][0]["route"] and r1_doc["e"] == 10.0
        assert doc["plan"]["teams"][0]["team"] is None and r1_doc["team"] is None  # one state: no team
        await view.stop()
        assert await _eof(stream)  # the open stream was closed
        assert asyncio.all_tasks() - before - {asyncio.current_task()} == set()  # nothing left running
        with pytest.raises(aiohttp.ClientConnectionError):
            await s.get(urls[0])  # the socket is closed too


async def test_watch_feeds_the_extra_view_and_stops_it() -> None:
    from fleetctl.bus.config import BusConfig
    from fleetctl.views.watch import RemoteFleetState, watch

    with socket.socket() as s:  # a port where no broker listens: the watcher keeps retrying
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    config = BusConfig("127.0.0.1", port, "test/web", False, None, None, None, None, None, None)
    seen: list[object] = []
    started = asyncio.Event()

    class Spy:
        def start(self, state: object, fleet: object) -> None:
            seen.append(state)
            started.set()

        async def stop(self) -> None:
            seen.append("stopped")

    task = asyncio.create_task(watch(config, headless=True, out=io.StringIO(),
                                     extra_view=Spy()))  # type: ignore[arg-type]
    await asyncio.wait_for(started.wait(), TIMEOUT)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert isinstance(seen[0], RemoteFleetState) and seen[-1] == "stopped"


@pytest.mark.parametrize(("args", "says"), [
    (["--tiles", "http://t/{z}/{x}/{y}.png"], "--tiles needs --web"),
    (["--web", "8080"], "give HOST:PORT"),
])
def test_bad_web_options_are_refused_before_flying(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                   args: list[str], says: str) -> None:
    from views_helpers import mission_dict, write_mission

    from fleetctl.cli import main

    m = write_mission(mission_dict(), tmp_path / "m.yaml")
    assert main(["deploy", "--mission", str(m), "--headless", "--runs", str(tmp_path / "runs"), *args]) == 2
    assert says in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()  # nothing flew


def test_tiles_are_placed_with_the_metres_per_degree_at_the_origin() -> None:
    from fleetctl.geo import Origin
    from fleetctl.views.web import map_config

    lat = 47.397742
    cfg = map_config(Origin(lat, 8.545594, 488.0), "http://t/{z}/{x}/{y}.png")
    assert cfg["tiles"] == "http://t/{z}/{x}/{y}.png"
    a, e2, phi = 6_378_137.0, 0.00669437999014, math.radians(lat)  # WGS84 radii of curvature there
    w = 1 - e2 * math.sin(phi) ** 2
    assert cfg["m_per_deg"]["lat"] == pytest.approx(math.radians(1) * a * (1 - e2) / w ** 1.5, rel=1e-4)
    assert cfg["m_per_deg"]["lon"] == pytest.approx(math.radians(1) * a / w ** 0.5 * math.cos(phi), rel=1e-4)
    assert map_config(None, None) == {"tiles": None}


# -- the token: bound beyond loopback the map and its stream need it --------------------------------

def test_the_token_is_needed_only_beyond_loopback() -> None:
    from fleetctl.views.web import TOKEN_ENV, is_loopback, map_token

    for host in ("127.0.0.1", "127.1.2.3", "::1", "localhost"):
        assert is_loopback(host) and map_token(host, {TOKEN_ENV: "x" * 20}) == (None, False)
    for host in ("0.0.0.0", "::", "192.168.1.7", "fleet-laptop"):
        assert not is_loopback(host)
        made, from_env = map_token(host, {})
        assert made is not None and len(made) >= 32 and not from_env
        assert map_token(host, {})[0] != made  # a new one at every start
        assert map_token(host, {TOKEN_ENV: "my-own.token_0123456789"}) == ("my-own.token_0123456789", True)
        for bad in ("short", "with space in the token", "x" * 129, "semi;colon-0123456789"):
            with pytest.raises(WebError, match=TOKEN_ENV):
                map_token(host, {TOKEN_ENV: bad})


async def test_beyond_loopback_page_and_stream_answer_401_or_403_without_the_token(tmp_path: Path) -> None:
    from fleetctl.views.web import map_token

    token, _ = map_token("0.0.0.0", {})
    st = state_of(mission(tmp_path), FakeClock())
    links: list[str] = []
    view = WebMapView("0.0.0.0", 0, on_ready=links.append, token=token)
    view.start(st, None)
    await asyncio.wait_for(view.ready.wait(), TIMEOUT)
    assert view.error is None and links[0].endswith(f"/?token={token}")
    base = f"http://127.0.0.1:{view.server.port}/"
    try:
        async with aiohttp.ClientSession() as s:  # no token: nothing of the map
            for route in ("", "events", "state", "static/map.js"):
                async with s.get(base + route) as r:
                    assert r.status == 401, route
            for wrong in (token[:-1] + ("A" if token[-1] != "A" else "B"), "x" * 500):
                async with s.get(base + "events", params={"token": wrong}) as r:
                    assert r.status == 403
                async with s.get(base, headers={"Authorization": f"Bearer {wrong}"}) as r:
                    assert r.status == 403
            async with s.get(base + "state", headers={"Authorization": f"Bearer {token}"}) as r:
                assert r.status == 200 and "frame" in await r.json()  # scripts: the bearer header
            assert not view.server.clients and view.server.unauthorised == 8
        # the printed link: the page, then its cookie (kept for an IP address, as a browser does)
        async with aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True)) as s:
            async with s.get(base, params={"token": token}) as r:
                assert r.status == 200 and "map.js" in await r.text()
                assert r.headers["Referrer-Policy"] == "no-referrer" and r.cookies[view.server.cookie]
            async with s.get(base + "static/map.js") as r:
                assert r.status == 200  # the cookie the link set
            stream = await s.get(base + "events")
            assert stream.status == 200 and (await _read_event(stream))[0] == "hello"
            stream.close()
    finally:
        await view.stop()


async def test_on_loopback_the_map_is_open(tmp_path: Path) -> None:
    from fleetctl.views.web import map_token

    token, _ = map_token("127.0.0.1", {})
    server = MapServer("127.0.0.1", 0, lambda: {"config": {}}, token=token)
    await server.start()
    try:
        assert server.link == server.url
        async with aiohttp.ClientSession() as s:
            for route in ("", "state", "static/map.css"):
                async with s.get(server.url + route) as r:
                    assert r.status == 200, route
    finally:
        await server.stop()


def test_the_cli_refuses_a_bad_token_in_the_environment(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    from views_helpers import mission_dict, write_mission

    from fleetctl.cli import main

    monkeypatch.setenv("FLEETCTL_WEB_TOKEN", "too short")
    m = write_mission(mission_dict(), tmp_path / "m.yaml")
    runs = str(tmp_path / "runs")
    args = ["deploy", "--mission", str(m), "--headless", "--runs", runs, "--web", "0.0.0.0:0"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "FLEETCTL_WEB_TOKEN: give 16 to 128 characters" in err and "Traceback" not in err
    assert not (tmp_path / "runs").exists()
