"""The live web map (``--web HOST:PORT``): a :class:`~fleetctl.views.view.View` that serves a
self-contained page (``web_static/``, shipped with the package: no CDN, no internet) and pushes
the run's state to it over server-sent events.

Routes: ``/`` the page, ``/static/<file>`` its script and style, ``/events`` the event stream
(``hello`` with the map's configuration, plan layer, trails and a frame; then ``plan`` when the
plan changes and ``frame`` a few times a second), ``/state`` the ``hello`` document as JSON.

Bounded: at most :data:`MAX_CLIENTS` streams (more get 503), each with a queue of
:data:`QUEUE_SIZE` messages; a client whose queue is full, or whose socket does not take a message
within :data:`WRITE_TIMEOUT` s, is dropped (its browser reconnects and starts again with
``hello``). The server runs in one task the view owns; :meth:`WebMapView.stop` cancels it, which
closes every stream and the listening socket. aiohttp is imported here only, so the command line
starts without it.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections.abc import Callable
from importlib import resources
from typing import TYPE_CHECKING, Any

from aiohttp import web

from fleetctl.journal import json_safe
from fleetctl.run.kinds import Ev
from fleetctl.views.map_model import Trails, frame, plan_layer
from fleetctl.views.view import View

if TYPE_CHECKING:
    from fleetctl.geo import Origin
    from fleetctl.mavlink.fleet import Fleet
    from fleetctl.run.state import FleetState

log = logging.getLogger(__name__)

MAX_CLIENTS = 16
QUEUE_SIZE = 32  # messages waiting per client (a few seconds of frames)
WRITE_TIMEOUT = 5.0  # s for one message to leave; slower clients are dropped
KEEPALIVE = 10.0  # s: a comment line when nothing else was sent
STOP_TIMEOUT = 5.0  # s for the server to close at shutdown
FRAME_HZ = 4.0
STATIC = {"map.js": "application/javascript", "map.css": "text/css", "index.html": "text/html"}


class WebError(Exception):
    """A ``--web`` address that cannot be used."""


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:PORT`` for IPv6) -> (host, port); :class:`WebError` when malformed."""
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise WebError(f"--web {text!r}: give HOST:PORT, e.g. 127.0.0.1:8080")
    return host, int(port)


def sse(event: str, data: Any) -> bytes:
    """One server-sent event."""
    return f"event: {event}\ndata: {json.dumps(json_safe(data), separators=(',', ':'))}\n\n".encode()


def static_file(name: str) -> bytes:
    return resources.files("fleetctl.views").joinpath("web_static").joinpath(name).read_bytes()


class MapClient:
    """One open event stream: a bounded queue of messages (``None`` = close)."""

    def __init__(self, size: int) -> None:
        self.queue: asyncio.Queue[bytes | None] = asyncio.Queue(size)
        self.closed = False

    def offer(self, msg: bytes) -> bool:
        """Queue ``msg``; False when the queue is full (the client is too slow)."""
        try:
            self.queue.put_nowait(msg)
            return True
        except asyncio.QueueFull:
            return False

    def close(self, drain: bool = False) -> None:
        """End the stream: at once, or (``drain``, at shutdown) after what is queued."""
        self.closed = True
        while not self.queue.empty() and (not drain or self.queue.full()):
            self.queue.get_nowait()
        self.queue.put_nowait(None)


class MapServer:
    """The HTTP side: page, static files and the bounded event streams."""

    def __init__(self, host: str, port: int, hello: Callable[[], dict[str, Any]], *,
                 max_clients: int = MAX_CLIENTS, queue_size: int = QUEUE_SIZE) -> None:
        self.host, self.port = host, port
        self.hello = hello  # the document a new page starts from
        self.max_clients, self.queue_size = max_clients, queue_size
        self.clients: set[MapClient] = set()
        self.refused = 0  # streams refused (too many clients)
        self.dropped = 0  # slow clients dropped
        self._runner: web.AppRunner | None = None
        self._files: dict[str, bytes] = {}  # the page's files, read once (off the loop) at start

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    async def start(self) -> None:
        self._files = await asyncio.to_thread(lambda: {name: static_file(name) for name in STATIC})
        app = web.Application()
        app.add_routes([web.get("/", self._page), web.get("/static/{name}", self._static),
                        web.get("/events", self._events), web.get("/state", self._state)])
        # handler_cancellation: a stream whose browser went away ends at once (not at its next write)
        self._runner = web.AppRunner(app, handle_signals=False, access_log=None, shutdown_timeout=1.0,
                                     handler_cancellation=True)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        try:
            await site.start()
        except OSError as exc:
            await self._runner.cleanup()
            why = exc.strerror or exc
            raise WebError(f"--web {self.host}:{self.port}: cannot listen there ({why})") from None
        addresses = self._runner.addresses  # the real port when 0 was asked for
        if addresses:
            self.port = int(addresses[0][1])

    def broadcast(self, msg: bytes) -> None:
        """Queue ``msg`` for every client; a client whose queue is full is dropped."""
        for c in list(self.clients):
            if not c.offer(msg):
                self.dropped += 1
                self._drop(c)

    def _drop(self, c: MapClient, drain: bool = False) -> None:
        if c in self.clients:
            self.clients.discard(c)
            c.close(drain)

    async def stop(self) -> None:
        """Close every stream (after the messages queued for it) and the listening socket."""
        for c in list(self.clients):
            self._drop(c, drain=True)
        if self._runner is not None:
            runner, self._runner = self._runner, None
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(STOP_TIMEOUT):
                    await runner.cleanup()

    # -- routes ------------------------------------------------------------------------------
    async def _page(self, request: web.Request) -> web.Response:
        return web.Response(body=self._files["index.html"], content_type="text/html")

    async def _static(self, request: web.Request) -> web.Response:
        name = request.match_info["name"]
        if name not in STATIC:
            raise web.HTTPNotFound()
        return web.Response(body=self._files[name], content_type=STATIC[name])

    async def _state(self, request: web.Request) -> web.Response:
        return web.json_response(json_safe(self.hello()))

    async def _events(self, request: web.Request) -> web.StreamResponse:
        if len(self.clients) >= self.max_clients:
            self.refused += 1
            return web.Response(status=503, text=f"at most {self.max_clients} map clients\n")
        client = MapClient(self.queue_size)
        self.clients.add(client)
        resp = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache"})
        try:
            await resp.prepare(request)
            await self._send(resp, sse("hello", self.hello()))
            await self._pump(client, resp)
        except (ConnectionError, TimeoutError):
            self.dropped += 1
        finally:
            self._drop(client)
        return resp

    async def _pump(self, client: MapClient, resp: web.StreamResponse) -> None:
        while True:
            try:
                msg = await asyncio.wait_for(client.queue.get(), KEEPALIVE)
            except TimeoutError:
                msg = b": keepalive\n\n"
            if msg is None:
                return
            await self._send(resp, msg)

    @staticmethod
    async def _send(resp: web.StreamResponse, msg: bytes) -> None:
        async with asyncio.timeout(WRITE_TIMEOUT):
            await resp.write(msg)


class WebMapView(View):
    """Serves the map of the :class:`FleetState` it is started with (see the module docstring)."""

    def __init__(self, host: str, port: int, *, origin: Origin | None = None, tiles: str | None = None,
                 hz: float = FRAME_HZ, on_ready: Callable[[str], None] | None = None,
                 max_clients: int = MAX_CLIENTS, queue_size: int = QUEUE_SIZE) -> None:
        self.server = MapServer(host, port, self.hello, max_clients=max_clients, queue_size=queue_size)
        self.config = map_config(origin, tiles)
        self.hz = hz
        self.on_ready = on_ready
        self.trails = Trails()
        self.error: str | None = None
        self.ready = asyncio.Event()
        self._state: FleetState | None = None
        self._plan: Any = None
        self._task: asyncio.Task[None] | None = None

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        self._state = state
        if self._task is None:
            self._task = asyncio.get_running_loop().create_task(self._serve(), name="web map")

    async def _serve(self) -> None:
        try:
            await self.server.start()
        except WebError as exc:
            self.error = str(exc)
            log.error("%s", exc)
            if self._state is not None:
                self._state.event(Ev.WEB_FAILED, f"web map: {exc}")
            self.ready.set()
            return
        self.ready.set()
        if self.on_ready is not None:
            self.on_ready(self.server.url)
        try:
            while True:
                self.tick()
                await asyncio.sleep(1.0 / self.hz)
        finally:
            await self.server.stop()

    def tick(self) -> None:
        """Push the state now (and the plan when it changed) to every client."""
        st = self._state
        if st is None:
            return
        self.trails.add(st)
        if st.plan is not self._plan:
            self._plan = st.plan
            self.server.broadcast(sse("plan", plan_layer(st)))
        self.server.broadcast(sse("frame", frame(st)))

    def hello(self) -> dict[str, Any]:
        """What a page opened now starts from: configuration, plan layer, trails, a frame."""
        st = self._state
        doc: dict[str, Any] = {"config": self.config}
        if st is not None:
            doc.update(plan=plan_layer(st), trails=self.trails.to_json(), frame=frame(st))
        return doc

    async def stop(self) -> None:
        task, self._task = self._task, None
        if task is None:
            return
        if not task.done():
            self.tick()  # the final state goes out before the streams close
            await asyncio.sleep(0)
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError, TimeoutError):
            async with asyncio.timeout(STOP_TIMEOUT + 1.0):
                await task


def map_config(origin: Origin | None, tiles: str | None) -> dict[str, Any]:
    """What the page needs besides the state: the tile template and, for it, the origin and the
    metres per degree there (from :mod:`fleetctl.geo`; the page only scales linearly)."""
    if origin is None:
        return {"tiles": None}
    from fleetctl.geo import geodetic_to_enu

    d = 1e-3
    north = geodetic_to_enu(origin.lat + d, origin.lon, origin.alt, origin)[1] / d
    east = geodetic_to_enu(origin.lat, origin.lon + d, origin.alt, origin)[0] / d
    return {"tiles": tiles, "origin": {"lat": origin.lat, "lon": origin.lon},
            "m_per_deg": {"lat": north, "lon": east}}


__all__ = ["FRAME_HZ", "MAX_CLIENTS", "QUEUE_SIZE", "MapClient", "MapServer", "WebError", "WebMapView",
           "map_config", "parse_address", "sse"]
