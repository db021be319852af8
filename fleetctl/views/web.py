"""The live web map (``--web HOST:PORT``): a :class:`~fleetctl.views.view.View` that serves a
self-contained page (``web_static/``, shipped with the package: no CDN, no internet) and pushes
the run's state to it over server-sent events.

Routes: ``/`` the page, ``/static/<file>`` its script and style, ``/events`` the event stream
(``hello`` with the map's configuration, plan layer, trails and a frame; then ``plan`` when the
plan changes and ``frame`` a few times a second), ``/state`` the ``hello`` document as JSON. The
map shows every team a run of several teams gives it (:mod:`fleetctl.views.map_model`).

Access: bound to a loopback address the map is open as it always was. Bound beyond loopback it
has a token (:func:`map_token`: from ``FLEETCTL_WEB_TOKEN`` or made at start) and every route
answers 401 (no token) or 403 (a wrong one) to a request that does not carry it: as
``?token=...`` (the page's link; the page then sets a cookie for the rest, so the event stream
and the static files carry it), as that cookie, or as ``Authorization: Bearer ...`` (scripts).
Tokens are compared with :func:`hmac.compare_digest`.

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
import hmac
import ipaddress
import json
import logging
import os
import re
import secrets
from collections.abc import Awaitable, Callable, Sequence
from importlib import resources
from typing import TYPE_CHECKING, Any

from aiohttp import web

from fleetctl.aio import cancel_and_wait
from fleetctl.journal import json_safe
from fleetctl.run.kinds import Ev
from fleetctl.views.map_model import Trails, teams_frame, teams_plan
from fleetctl.views.teams import ShownTeams
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
TOKEN_ENV = "FLEETCTL_WEB_TOKEN"
TOKEN_RE = re.compile(r"[A-Za-z0-9._~-]{16,128}")  # a token given in TOKEN_ENV (URL-safe, no escaping)
MAX_TOKEN = 128  # characters: a longer token in a request is refused without comparing


class WebError(Exception):
    """A ``--web`` address (or token) that cannot be used."""


def is_loopback(host: str) -> bool:
    """``host`` is this machine only (127.0.0.0/8, ::1, localhost): the map needs no token there."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a host name or an interface: reachable from elsewhere


def map_token(host: str, environ: dict[str, str] | None = None) -> tuple[str | None, bool]:
    """The token the map at ``host`` requires and whether it came from :data:`TOKEN_ENV`: (None,
    False) on loopback; the variable's value when set (:class:`WebError` unless it is 16 to 128
    characters of ``A-Z a-z 0-9 . _ ~ -``); else a new random one (32 URL-safe characters)."""
    if is_loopback(host):
        return None, False
    env = os.environ if environ is None else environ
    given = env.get(TOKEN_ENV)
    if given is None:
        return secrets.token_urlsafe(24), False
    if not TOKEN_RE.fullmatch(given):
        raise WebError(f"{TOKEN_ENV}: give 16 to 128 characters of A-Z a-z 0-9 . _ ~ - (it is the map's "
                       "token, part of its link)")
    return given, True


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
                 max_clients: int = MAX_CLIENTS, queue_size: int = QUEUE_SIZE,
                 token: str | None = None) -> None:
        self.host, self.port = host, port
        self.hello = hello  # the document a new page starts from
        self.max_clients, self.queue_size = max_clients, queue_size
        self.token = token  # None: open (loopback); else every route requires it
        self.clients: set[MapClient] = set()
        self.refused = 0  # streams refused (too many clients)
        self.unauthorised = 0  # requests refused for a missing or wrong token
        self.dropped = 0  # slow clients dropped
        self._runner: web.AppRunner | None = None
        self._files: dict[str, bytes] = {}  # the page's files, read once (off the loop) at start

    @property
    def url(self) -> str:
        """The page's address (without the token)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    @property
    def link(self) -> str:
        """The address that opens the page: with ``?token=`` when the map has a token."""
        return self.url if self.token is None else f"{self.url}?token={self.token}"

    @property
    def cookie(self) -> str:
        """The token's cookie (one per port: cookies do not tell ports apart)."""
        return f"fleetctl_map_{self.port}"

    def _given(self, request: web.Request) -> str | None:
        """The token a request carries: ``?token=``, ``Authorization: Bearer``, or the cookie."""
        auth = request.headers.get("Authorization", "")
        for given in (request.query.get("token"), auth[7:] if auth.startswith("Bearer ") else None,
                      request.cookies.get(self.cookie)):
            if given:
                return given
        return None

    @web.middleware
    async def _guard(self, request: web.Request,
                     handler: Callable[[web.Request], Awaitable[web.StreamResponse]]) -> web.StreamResponse:
        """Every route requires the token when the map has one: 401 without it, 403 when wrong."""
        if self.token is None:
            return await handler(request)
        given = self._given(request)
        if given is None:
            self.unauthorised += 1
            return web.Response(status=401, headers={"WWW-Authenticate": "Bearer"},
                                text="this map needs its token: open the link fleetctl printed when it "
                                     "started (http://HOST:PORT/?token=...)\n")
        if len(given) > MAX_TOKEN or not hmac.compare_digest(given.encode(), self.token.encode()):
            self.unauthorised += 1
            return web.Response(status=403, text="wrong token for this map\n")
        resp: web.StreamResponse = await handler(request)
        if resp.prepared:  # the event stream: its headers are out
            return resp
        resp.headers["Referrer-Policy"] = "no-referrer"  # the link's token goes nowhere else (tiles)
        if request.query.get("token") and request.cookies.get(self.cookie) != self.token:
            # the page's link: the page's script, style and event stream then carry the cookie
            resp.set_cookie(self.cookie, self.token, httponly=True, samesite="Strict", path="/")
        return resp

    async def start(self) -> None:
        self._files = await asyncio.to_thread(lambda: {name: static_file(name) for name in STATIC})
        app = web.Application(middlewares=[self._guard])
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
                 max_clients: int = MAX_CLIENTS, queue_size: int = QUEUE_SIZE,
                 token: str | None = None) -> None:
        """``on_ready`` gets the page's link (with its token, if any) once the map listens."""
        self.server = MapServer(host, port, self.hello, max_clients=max_clients, queue_size=queue_size,
                                token=token)
        self.config = map_config(origin, tiles)
        self.hz = hz
        self.on_ready = on_ready
        self.trails = Trails()
        self.error: str | None = None
        self.ready = asyncio.Event()
        self.teams = ShownTeams()
        self._plans: list[Any] = []  # the plans last sent (their identities: a new one is sent again)
        self._task: asyncio.Task[None] | None = None

    @property
    def _state(self) -> FleetState | None:
        """The state events go to (the first team's with several)."""
        shown = self.teams.shown()
        return self.teams.main if self.teams.main is not None else (shown[0].state if shown else None)

    def start(self, state: FleetState, fleet: Fleet | None) -> None:
        self.teams.set_main(state)
        self._serve_once()

    def declare_teams(self, teams: Sequence[str], *, every: bool = False) -> None:
        self.teams.declare(teams, every=every)

    def start_team(self, team: str, state: FleetState, fleet: Fleet | None) -> None:
        """Draw ``team``'s state beside the other teams' (in its colour)."""
        self.teams.set_team(team, state)
        self._serve_once()

    def _serve_once(self) -> None:
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
            self.on_ready(self.server.link)
        try:
            while True:
                self.tick()
                await asyncio.sleep(1.0 / self.hz)
        finally:
            await self.server.stop()

    def _plan_ids(self) -> list[Any]:
        return [(t.team, id(t.state), id(t.state.plan)) for t in self.teams.shown()]

    def tick(self) -> None:
        """Push the state now (and the plans when a team's changed) to every client."""
        if not self.teams.shown():
            return
        self.trails.add_teams(self.teams)
        plans = self._plan_ids()
        if plans != self._plans:
            self._plans = plans
            self.server.broadcast(sse("plan", teams_plan(self.teams)))
        self.server.broadcast(sse("frame", teams_frame(self.teams)))

    def hello(self) -> dict[str, Any]:
        """What a page opened now starts from: configuration, plan layer, trails, a frame."""
        doc: dict[str, Any] = {"config": self.config}
        if self.teams.shown():
            doc.update(plan=teams_plan(self.teams), trails=self.trails.to_json(),
                       frame=teams_frame(self.teams))
        return doc

    async def stop(self) -> None:
        task, self._task = self._task, None
        if task is None:
            return
        if not task.done():
            self.tick()  # the final state goes out before the streams close
            await asyncio.sleep(0)
        await cancel_and_wait(task, timeout=STOP_TIMEOUT + 1.0)


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


__all__ = ["FRAME_HZ", "MAX_CLIENTS", "QUEUE_SIZE", "TOKEN_ENV", "MapClient", "MapServer", "WebError",
           "WebMapView", "is_loopback", "map_config", "map_token", "parse_address", "sse"]
