"""``--web HOST:PORT`` (and ``--tiles``) of the flying commands, ``watch`` and ``replay``: the web
map beside the terminal view (docs/web-map.md). The map's server (aiohttp) is imported only when
``--web`` is given."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

from fleetctl.cli.errors import CliError
from fleetctl.views.dashboard import HeadlessView
from fleetctl.views.view import View, Views

if TYPE_CHECKING:
    from fleetctl.geo import Origin
    from fleetctl.views.web import WebMapView


def web_view(args: argparse.Namespace, origin: Origin | None, headless: bool) -> WebMapView | None:
    """The web map view of ``--web`` (None without it); refuses a bad address, a bad
    FLEETCTL_WEB_TOKEN or --tiles alone. Bound beyond loopback the map has a token: its link is
    printed once (``web map: http://HOST:PORT/?token=...``: with --headless when the map listens,
    else before the live view starts); a token from the environment is not printed."""
    if getattr(args, "tiles", None) and not args.web:
        raise CliError("--tiles needs --web HOST:PORT")
    if not getattr(args, "web", None):
        return None
    from fleetctl.views.web import TOKEN_ENV, WebError, WebMapView, map_token, parse_address  # aiohttp

    try:
        host, port = parse_address(args.web)
        token, from_env = map_token(host)
    except WebError as e:
        raise CliError(str(e)) from None
    if args.tiles and origin is None:
        raise CliError("--tiles needs the mission origin: watch has no mission file (use replay or the "
                       "flying commands)")
    line = _link_line(token, from_env, TOKEN_ENV)

    def ready(link: str) -> None:
        if headless:
            print(line(link), flush=True)

    if not headless and token is not None and port != 0:  # once, before the live view takes the terminal
        shown = f"[{host}]" if ":" in host else host
        print(line(f"http://{shown}:{port}/?token={token}"), flush=True)
    return WebMapView(host, port, origin=origin, tiles=args.tiles, on_ready=ready, token=token)


def _link_line(token: str | None, from_env: bool, env: str) -> Callable[[str], str]:
    """The line that names the map's link (without the token when it came from the environment
    variable ``env``)."""

    def line(link: str) -> str:
        if token is None:
            return f"web map: {link}"
        url = link.split("?", 1)[0]
        if from_env:
            return f"web map: {url}?token=${env} (the token in {env}: bound beyond loopback)"
        return f"web map: {link} (the token is required: bound beyond loopback; {env} sets your own)"

    return line


def with_web(args: argparse.Namespace, view: View, origin: Origin | None) -> View:
    """``view`` plus the web map of ``--web`` (its address shown as a status line of the live view)."""
    web = web_view(args, origin, isinstance(view, HeadlessView))
    if web is None:
        return view
    any_port = web.server.port == 0  # chosen when it listens: its link was not printed
    add_status = getattr(view, "add_status", None)
    if add_status is not None:
        def line() -> str:
            server = web.server
            if web.error or server.token is None:
                return f"web map: {web.error or server.url}"
            if any_port:
                return f"web map: {server.link}"
            return f"web map: {server.url} (token required: its link was printed at start)"

        add_status(line)
    return Views(view, web)
