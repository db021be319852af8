"""Connection strings users bring from other ground stations, in fleetctl's own spelling.

fleetctl writes a connection from the controller's side (docs/mavlink.md): ``udpin://HOST:PORT``
listens, ``udp://HOST:PORT`` (alias ``udpout://``) sends to a vehicle listening there,
``tcp://HOST:PORT`` connects, ``serial:///dev/NAME?baud=N`` (``serial://COM3?baud=N``) opens a
serial port. MAVSDK, pymavlink and MAVProxy spell some of these differently; where their meaning is
unambiguous :func:`normalize_connection` maps them to fleetctl's form, otherwise it raises
:class:`ConnectionSpellingError` naming fleetctl's equivalent.
"""

from __future__ import annotations

import re

_HOST = r"(?P<host>\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]*)"
_PORT = r"(?P<port>\d+)"
_URL = re.compile(rf"(?P<scheme>[A-Za-z]+)://{_HOST}:{_PORT}/?")  # MAVSDK and fleetctl
_COLON = re.compile(rf"(?P<scheme>udpin|udpout|udp|udpbcast|tcp|tcpin):{_HOST}:{_PORT}", re.I)  # pymavlink
_DEVICE = r"(?P<dev>/dev/[^?,:\s]+|COM\d+|/[^?,:\s]+)"
_SERIAL_URL = re.compile(rf"serial://{_DEVICE}(?::(?P<baud>\d+)|\?baud(?:rate)?=(?P<qbaud>\d+))?", re.I)
_BARE_DEVICE = re.compile(rf"{_DEVICE}(?:[,:](?P<baud>\d+))?", re.I)

TCP_LISTEN = ("fleetctl does not listen for TCP connections; let the vehicle (or mavlink-router) "
              "listen and write tcp://HOST:{port} to connect to it, or use udpin://0.0.0.0:{port}")


class ConnectionSpellingError(ValueError):
    """A connection string whose meaning in fleetctl is not clear; the message says what to write."""


def normalize_connection(text: str) -> str:
    """``text`` in fleetctl's spelling (unchanged when it is one already, or not recognised: the
    caller's own check then reports it). Raises :class:`ConnectionSpellingError`."""
    s = text.strip()
    for form in (_url, _colon_form, _serial_url, _bare_device):
        out = form(s)
        if out is not None:
            return out
    return s


def _url(s: str) -> str | None:
    m = _URL.fullmatch(s)
    if m is None:
        return None
    scheme, host, port = m["scheme"].lower(), m["host"], m["port"]
    if scheme in ("udp", "udpin") and not host:  # MAVSDK: listen on every interface
        return f"udpin://0.0.0.0:{port}"
    if scheme in ("udp", "udpout") and host == "0.0.0.0":
        raise ConnectionSpellingError(
            f"{s!r} would send to 0.0.0.0; to listen on port {port} (MAVSDK's udp://:{port}) write "
            f"udpin://0.0.0.0:{port}, to send to a vehicle write udp://VEHICLE_HOST:{port}")
    if scheme in ("udpout", "tcp", "tcpout") and not host:
        want = "udp" if scheme == "udpout" else "tcp"
        raise ConnectionSpellingError(f"{s!r} names no host to send to; write {want}://HOST:{port}")
    if scheme == "tcpout":  # MAVSDK 2
        return f"tcp://{host}:{port}"
    if scheme == "tcpin":
        raise ConnectionSpellingError(f"{s!r}: " + TCP_LISTEN.format(port=port))
    if scheme in ("udp", "udpout", "udpin", "tcp"):
        return f"{scheme}://{host}:{port}"
    return None


def _colon_form(s: str) -> str | None:
    m = _COLON.fullmatch(s)
    if m is None:
        return None
    scheme, host, port = m["scheme"].lower(), m["host"], m["port"]
    if scheme == "udpin":
        return f"udpin://{host or '0.0.0.0'}:{port}"
    if scheme in ("udpout", "tcp") and host:
        return f"{'udp' if scheme == 'udpout' else 'tcp'}://{host}:{port}"
    if scheme == "udp":  # pymavlink/MAVProxy udp: listens, fleetctl's udp:// sends
        raise ConnectionSpellingError(
            f"{s!r} is ambiguous (pymavlink's and MAVProxy's udp: listens, fleetctl's udp:// sends); "
            f"write udpin://{host or '0.0.0.0'}:{port} to listen there, or udp://{host or 'HOST'}:{port} "
            "to send to a vehicle listening there")
    if scheme == "udpbcast":
        raise ConnectionSpellingError(f"{s!r}: UDP broadcast is not supported; listen with "
                                      f"udpin://0.0.0.0:{port}")
    if scheme == "tcpin":
        raise ConnectionSpellingError(f"{s!r}: " + TCP_LISTEN.format(port=port))
    raise ConnectionSpellingError(f"{s!r} names no host; write {scheme.replace('udpout', 'udp')}://HOST:{port}")


def _serial(dev: str, baud: str | None, given: str) -> str:
    url = "serial://" + (dev.upper() if dev.upper().startswith("COM") else dev)
    if baud is None:
        raise ConnectionSpellingError(f"{given!r} gives no baud rate; write {url}?baud=57600 "
                                      "(or your radio's rate)")
    return f"{url}?baud={baud}"


def _serial_url(s: str) -> str | None:
    m = _SERIAL_URL.fullmatch(s)
    if m is None:
        return None
    return _serial(m["dev"], m["baud"] or m["qbaud"], s)


def _bare_device(s: str) -> str | None:
    m = _BARE_DEVICE.fullmatch(s)
    if m is None or not (m["dev"].startswith("/dev/") or m["dev"].upper().startswith("COM")):
        return None
    return _serial(m["dev"], m["baud"], s)


__all__ = ["ConnectionSpellingError", "normalize_connection"]
