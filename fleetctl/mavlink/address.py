"""Connection URLs, written from the controller's side (docs/mavlink.md): :func:`parse_url` turns
one into a :class:`LinkAddress` or says, in a :class:`~fleetctl.mavlink.errors.LinkError`, what to
write instead."""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

from fleetctl.mavlink.errors import LinkError


@dataclass(frozen=True)
class LinkAddress:
    """A parsed connection URL. ``kind`` is ``udpin``, ``udpout``, ``tcp`` or ``serial``."""

    url: str
    kind: str
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 57600


def parse_url(url: str) -> LinkAddress:
    """Parse a controller-side connection URL; :class:`LinkError` says what to write instead."""
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme == "serial":
        device = parts.path or parts.netloc
        if not device:
            raise LinkError(f"connection {url!r}: needs a device, e.g. serial:///dev/ttyACM0?baud=57600")
        q = parse_qs(parts.query)
        try:
            baud = int(q.get("baud", q.get("baudrate", ["57600"]))[0])
        except ValueError:
            raise LinkError(f"connection {url!r}: baud must be an integer") from None
        return LinkAddress(url, "serial", device=device, baud=baud)
    if scheme not in ("udpin", "udp", "udpout", "tcp"):
        raise LinkError(f"connection {url!r}: unknown scheme; use udpin://HOST:PORT, udp://HOST:PORT, "
                        "tcp://HOST:PORT or serial:///dev/X?baud=N")
    try:
        port = parts.port
    except ValueError:
        port = None
    if port is None or (port == 0 and scheme != "udpin"):
        raise LinkError(f"connection {url!r}: needs a port, e.g. {scheme}://127.0.0.1:14550")
    host = parts.hostname or ("0.0.0.0" if scheme == "udpin" else "127.0.0.1")
    kind = "udpout" if scheme in ("udp", "udpout") else scheme
    return LinkAddress(url, kind, host=host, port=port)


__all__ = ["LinkAddress", "parse_url"]
