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
        assert doc["plan"]["route"] and r1_doc["e"] == 10.0
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
