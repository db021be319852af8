"""The bus settings of a run: from the mission's ``mqtt:`` section or the command line."""

from __future__ import annotations

import os
import re
import ssl
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from fleetctl.kinds import Ev

if TYPE_CHECKING:
    from fleetctl.mission import Mission, MqttConfig


TELEMETRY_HZ = 2.0
BUFFER_SIZE = 2000  # messages held while the broker is away
CONNECT_TIMEOUT = 5.0  # s for the broker's CONNACK (aiomqtt's timeout); a whole attempt, TCP included: 2x
PUBLISH_TIMEOUT = 5.0  # s for a QoS 1 PUBACK
BACKOFF_MIN = 0.2  # s before the first reconnect
BACKOFF_MAX = 5.0
STATUS_INTERVAL = 1.0  # s between retained status updates (and on every change)
MAX_MESSAGE = 64 * 1024  # bytes of an incoming task message
MAX_JSON_DEPTH = 16  # nesting of lists/objects in an incoming task message (a task message needs 4)
MAX_PENDING = 32  # task changes queued before the controller can take them (oldest refused)
FINAL_STATES = ("done", "failed", "interrupted", "offline")


class BusStatus(StrEnum):
    """Where a client's connection to the broker stands (docs/mqtt.md, connection state): the
    ``bus`` field of ``P/status``, the summary's ``mqtt.state``, the ``bus_<status>`` events."""

    CONNECTING = "connecting"  # the first attempt under way
    CONNECTED = "connected"
    RECONNECTING = "reconnecting"  # an attempt failed or the connection was lost; retrying
    CLOSED = "closed"  # the run closed it
    FAILED = "failed"  # the bus task ended on an error (a bug): no MQTT for the rest of the run
    STOPPED = "stopped"  # fleetctl watch: stopped (Ctrl-C, --exit-on-done)

# the event told when the connection moves to one of these states (the others are not told)
STATUS_EVENT = {BusStatus.CONNECTED: Ev.BUS_CONNECTED, BusStatus.RECONNECTING: Ev.BUS_RECONNECTING,
                BusStatus.FAILED: Ev.BUS_FAILED}

_URL = re.compile(r"(?P<scheme>mqtts?)://(?P<host>[A-Za-z0-9_.-]+)(?::(?P<port>\d{1,5}))?/?")


class BusConfigError(ValueError):
    """A bus setting the user can fix (bad URL, missing password variable, unreadable TLS file)."""


class Secret(str):
    """A string whose repr/str in messages never shows the value."""

    def __repr__(self) -> str:
        return "'***'"


@dataclass(frozen=True)
class BusConfig:
    host: str
    port: int
    topic_prefix: str
    tls: bool = False
    client_id: str | None = None
    username: str | None = None
    password: Secret | None = None
    ca: str | None = None
    cert: str | None = None
    key: str | None = None
    telemetry_hz: float = TELEMETRY_HZ
    buffer_size: int = BUFFER_SIZE
    accept_task_changes: bool = False  # the mission's mqtt.accept_task_changes

    @property
    def url(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.host}:{self.port}"

    def __repr__(self) -> str:  # never the password
        return (f"BusConfig(url={self.url!r}, topic_prefix={self.topic_prefix!r}, "
                f"client_id={self.client_id!r}, username={self.username!r})")

    def ssl_context(self) -> ssl.SSLContext | None:
        """The TLS context from ``ca``/``cert``/``key`` (reads files: call off the event loop)."""
        if not self.tls:
            return None
        try:
            ctx = ssl.create_default_context(cafile=self.ca)
            if self.cert is not None:
                ctx.load_cert_chain(self.cert, self.key)
        except (OSError, ssl.SSLError) as exc:
            raise BusConfigError(f"mqtt.tls: cannot load the TLS files (ca {self.ca!r}, cert {self.cert!r}, "
                                 f"key {self.key!r}): {exc}") from None
        return ctx


def parse_url(url: str) -> tuple[str, int, bool]:
    """``mqtt://HOST[:PORT]`` (1883) or ``mqtts://HOST[:PORT]`` (8883, TLS) → (host, port, tls)."""
    m = _URL.fullmatch(url.strip())
    if m is None:
        raise BusConfigError(f"{url.split('@')[-1]!r} is not an MQTT broker URL; use mqtt://HOST[:PORT] "
                             "or mqtts://HOST[:PORT] (user name in mqtt.username, password via "
                             "mqtt.password_env)")
    tls = m["scheme"] == "mqtts"
    port = int(m["port"]) if m["port"] else (8883 if tls else 1883)
    if not 1 <= port <= 65535:
        raise BusConfigError(f"MQTT port {port} is out of range 1..65535")
    return m["host"], port, tls


def bus_config(mission: Mission, url: str | None = None, topic_prefix: str | None = None,
               telemetry_hz: float = TELEMETRY_HZ) -> BusConfig | None:
    """The bus settings of a run: the mission's ``mqtt:`` section, ``url``/``topic_prefix`` (the
    ``--mqtt``/``--topic-prefix`` options) overriding it; None (bus off) when neither gives a URL."""
    m: MqttConfig | None = mission.mqtt
    url = url or (m.url if m is not None else None)
    if url is None:
        return None
    host, port, tls = parse_url(url)
    prefix = topic_prefix or (m.topic_prefix if m is not None else None) or f"fleetctl/{mission.name}"
    prefix = prefix.strip("/")
    if not prefix or any(c in prefix for c in "+#\0"):
        raise BusConfigError(f"topic prefix {prefix!r}: use a non-empty MQTT topic without '+', '#'")
    password = None
    if m is not None and m.password_env:
        value = os.environ.get(m.password_env)
        if value is None:
            raise BusConfigError(f"mqtt.password_env: the environment variable {m.password_env} is not set; "
                                 "export it with the broker password")
        password = Secret(value)
    t = m.tls if m is not None else None
    if t is not None and (t.ca or t.cert):
        tls = True
    if not telemetry_hz > 0:
        raise BusConfigError(f"telemetry rate must be > 0 Hz, got {telemetry_hz}")
    return BusConfig(host, port, prefix, tls, m.client_id if m else None, m.username if m else None, password,
                     t.ca if t else None, t.cert if t else None, t.key if t else None, telemetry_hz,
                     accept_task_changes=bool(m.accept_task_changes) if m is not None else False)


def client_kwargs(config: BusConfig, ssl_context: ssl.SSLContext | None) -> dict[str, Any]:
    """Keyword arguments for :class:`aiomqtt.Client` (shared with ``fleetctl watch``)."""
    return {"hostname": config.host, "port": config.port, "username": config.username,
            "password": str(config.password) if config.password is not None else None,
            "tls_context": ssl_context, "timeout": CONNECT_TIMEOUT, "keepalive": 10}
