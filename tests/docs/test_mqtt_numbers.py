"""Every number docs/mqtt.md states about the bus is the code's.

Each number in the prose (outside code blocks, inline code and the example payloads) must be read
by one of the phrases below, which names the constant it comes from; a new number in the doc, or
a changed constant, fails until both agree."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from fleetctl.bus import config as bus
from fleetctl.bus.teams import board, protocol
from fleetctl.mission import limits
from fleetctl.run.teams import link
from fleetctl.views import watch

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "mqtt.md"

# a phrase of docs/mqtt.md with its numbers as groups -> what the code has
PHRASES: list[tuple[str, tuple[float, ...]]] = [
    (r"mqtt://HOST\[:PORT\]`? \((\d+)\) or `?mqtts://HOST\[:PORT\]`? \((\d+), TLS\)",
     (bus.parse_url("mqtt://h")[1], bus.parse_url("mqtts://h")[1])),
    (r"QoS 0, (\d+) Hz", (bus.TELEMETRY_HZ,)),
    (r"at most (\d+) KiB, JSON\s+nested at most (\d+) deep", (bus.MAX_MESSAGE / 1024, bus.MAX_JSON_DEPTH)),
    (r"queued \(up to (\d+)\)", (bus.MAX_PENDING,)),
    (r"(\d+) s later \(`HANDOVER_GRACE`\)", (board.HANDOVER_GRACE,)),
    (r"carrier link is lost for (\d+) s", (link.CARRIER_RELEASE_AFTER,)),
    (r"unclaimed (\d+) s later\s+\(`UNCLAIMED_AFTER`", (link.UNCLAIMED_AFTER,)),
    (r"for ([\d.]+) s \(`CLAIM_SETTLE`\)", (board.CLAIM_SETTLE,)),
    (r"at most (\d+) KiB, nested at most (\d+) deep, typed", (protocol.MAX_PEER_MESSAGE / 1024,
                                                             protocol.MAX_PEER_DEPTH)),
    (r"ids of at most (\d+) characters", (protocol.MAX_ID,)),
    (r"`team_message_rejected`, the first (\d+)\)", (link.MAX_REJECT_RECORDS,)),
    (r"back off from ([\d.]+) s to ([\d.]+) s \(`BACKOFF_MIN`, `BACKOFF_MAX`\)",
     (bus.BACKOFF_MIN, bus.BACKOFF_MAX)),
    (r"CONNACK\s+is awaited at most (\d+) s \(`CONNECT_TIMEOUT`\)", (bus.CONNECT_TIMEOUT,)),
    (r"a whole connection attempt \(TCP, TLS and CONNACK\) at\s+most (\d+) s \(twice `CONNECT_TIMEOUT`\)",
     (2 * bus.CONNECT_TIMEOUT,)),
    (r"telemetry at (\d+) Hz per vehicle, a buffer of (\d+) messages", (bus.TELEMETRY_HZ, bus.BUFFER_SIZE)),
    (r"status republished every (second)", (bus.STATUS_INTERVAL,)),
    (r"incoming task messages of\s+at most (\d+) KiB nested at most (\d+) deep, (\d+) task changes queued",
     (bus.MAX_MESSAGE / 1024, bus.MAX_JSON_DEPTH, bus.MAX_PENDING)),
    (r"than (\d+) x the\s+mission's extent", (limits.FAR_FACTOR,)),
    (r"distance in the mission file, at least (\d+) m\)", (limits.MIN_EXTENT,)),
    (r"a message over (\d+) MiB, a team id that is not (\d+) to (\d+) characters",
     (watch.MAX_PAYLOAD / 2**20, *map(int, re.findall(r"\{(\d+),(\d+)\}", watch.ID_RE.pattern)[0]))),
]
WORDS = {"second": 1.0}
# numbers that are facts of MQTT or of the command line, not settings of the bus
NOT_SETTINGS = [r"QoS [01]\b", r"epoch \+ 1\b", r"exits with status 0\b"]


def _prose() -> str:
    """docs/mqtt.md without code blocks, inline code and table cells of example payloads (blanked
    to spaces, so positions stay those of the file)."""
    text = DOC.read_text(encoding="utf-8")
    def blank(m: re.Match[str]) -> str:
        return re.sub(r"\S", " ", m[0])

    text = re.sub(r"```.*?```", blank, text, flags=re.S)
    return re.sub(r"`[^`\n]*`", blank, text)


@pytest.mark.parametrize(("phrase", "values"), PHRASES, ids=[p[:40] for p, _ in PHRASES])
def test_the_number_is_the_codes(phrase: str, values: tuple[float, ...]) -> None:
    m = re.search(phrase, DOC.read_text(encoding="utf-8"))
    assert m, f"docs/mqtt.md no longer says {phrase!r}: update the doc or this test"
    said = tuple(WORDS.get(g, None) or float(g) for g in m.groups())
    assert said == tuple(float(v) for v in values), f"docs/mqtt.md says {m[0]!r}; the code: {values}"


def test_every_number_in_the_prose_is_checked() -> None:
    text = DOC.read_text(encoding="utf-8")
    covered: set[int] = set()
    for phrase in [p for p, _ in PHRASES] + NOT_SETTINGS:
        for m in re.finditer(phrase, text):
            covered |= set(range(m.start(), m.end()))
    numbers = re.finditer(r"(?<![\w.])\d+(\.\d+)?(?![\w.])", _prose())
    unchecked = [(text.count("\n", 0, m.start()) + 1, m[0]) for m in numbers if m.start() not in covered]
    assert not unchecked, f"numbers in docs/mqtt.md not compared with the code (line, number): {unchecked}"


def test_a_connection_attempt_is_bounded_by_twice_the_connect_timeout() -> None:
    """The 10 s of the doc: the connect of the bus and of watch (``client.__aenter__()``, in the
    reconnect helper they share) runs under ``asyncio.timeout(CONNECT_TIMEOUT * 2)``."""
    tree = ast.parse((ROOT / "fleetctl" / "bus" / "reconnect.py").read_text(encoding="utf-8"))
    bounds = [ast.unparse(item.context_expr) for n in ast.walk(tree) if isinstance(n, ast.AsyncWith)
              for item in n.items if "__aenter__" in ast.unparse(n)]
    assert bounds == ["asyncio.timeout(CONNECT_TIMEOUT * 2)"]
